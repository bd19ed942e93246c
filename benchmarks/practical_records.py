"""Benchmark: on the records people have, does the diagnosis name only what it can
tell, and say "cannot tell" otherwise?

Runs `jaxhyst diagnose` on `jh.synthetic.practical_recording` cases: plain drives (one
sine, two sines summed or in sequence, a switch-on hold then a sine, a short record
of five periods) x {no effect, each of the six effects alone} x `--cases` seeds,
under white (or `--noise coloured`) sensor noise. The records are diagnosed in one
`jh.batch` (CSV files and a manifest, `--model piezo`, each record's diagnosis key as
its `seed`) on `--workers` workers of one thread (2); `--out DIR` keeps the batch
folder. On such records some effects look
alike (a delay of the drive, a rate dependence and creep on one 1 Hz sine), so a
right answer is either the exact set or a statement that the record cannot tell.

Each case is classified (`classify`):
- "exact": the named set equals the concealed set;
- "cannot tell": not exact, but every effect missed or named in excess is one the
  diagnosis says it cannot tell about (`Diagnosis.undecided`); this counts as right;
- "false claim": an effect named that is neither concealed nor flagged undecided
  (counts as a miss, and takes precedence);
- "missed": otherwise (a concealed effect neither named nor flagged).

Per seed, every excitation and effect shares the base model and the noise level
(the same generation key), so the cases differ only by what is compared.

    python benchmarks/practical_records.py                 # 5 drives x 7, 1 seed
    python benchmarks/practical_records.py --quick         # a smoke run (2 cases)
    python benchmarks/practical_records.py --dry-run       # generate only
    python benchmarks/practical_records.py --excitations switch-on short \\
        --effects none creep input_bias --json out.json
"""

import argparse
import statistics
import sys
import time
from typing import Any

import jax


jax.config.update("jax_enable_x64", True)

import _common as common  # noqa: E402
import numpy as np  # noqa: E402
from concealed_effects import EFFECTS  # noqa: E402

import jaxhyst as jh  # noqa: E402


# name -> (the drive, its duration in seconds)
EXCITATIONS: dict[str, tuple[jh.synthetic.AbstractExcitation, float]] = {
    "sine-1hz": (jh.synthetic.SineExcitation((1.0,)), 20.0),
    "two-sines": (jh.synthetic.SineExcitation((1.0, 5.0)), 20.0),
    "sequence": (jh.synthetic.SineExcitation((0.5, 2.0), in_sequence=True), 20.0),
    "switch-on": (jh.synthetic.SwitchOnSine(1.0, hold=2.0), 20.0),
    "short": (jh.synthetic.SineExcitation((1.0,)), 5.0),
}
SINGLE_FREQUENCY = ("sine-1hz", "switch-on", "short")
EFFECT_CHOICES = ("none", *EFFECTS)
CLASSES = ("exact", "cannot tell", "false claim", "missed")
RIGHT = ("exact", "cannot tell")
QUICK = (("sine-1hz",), ("none", "creep"), 500.0)  # excitations, effects, rate


def classify(
    truth: frozenset[str], named: frozenset[str], undecided: frozenset[str]
) -> str:
    """One of CLASSES for a diagnosis that named `named` and said it cannot tell
    about `undecided`, on a record concealing `truth`."""
    truth, named, undecided = frozenset(truth), frozenset(named), frozenset(undecided)
    if named - truth - undecided:
        return "false claim"
    if named == truth:
        return "exact"
    if (named ^ truth) <= undecided:
        return "cannot tell"
    return "missed"


def build_cases(
    excitations: tuple[str, ...], effects: tuple[str, ...], seeds: int
) -> list[dict[str, Any]]:
    return [
        {
            "excitation": excitation,
            "effects": () if effect == "none" else (effect,),
            "seed": seed,
        }
        for seed in range(seeds)
        for excitation in excitations
        for effect in effects
    ]


def _label(effects) -> str:
    return common.effects_label(effects, none="none")


def generate_case(spec, args) -> tuple[dict[str, Any], Any, Any]:
    """The case's record, its recording and its diagnosis key."""
    excitation, duration = EXCITATIONS[spec["excitation"]]
    # The keys of the seed, not of the case: shared by every excitation and effect,
    # so that a seed's records share their base model and noise level.
    generate_key, diagnose_key = common.case_keys(args.seed, spec["seed"])
    start = time.perf_counter()
    case = jh.synthetic.practical_recording(
        spec["effects"],
        key=generate_key,
        excitation=excitation,
        duration=duration,
        rate=args.rate,
        noise=args.noise,
        size_sigmas=args.size,
    )
    result: dict[str, Any] = {
        "excitation": spec["excitation"],
        "input": excitation.describe(),
        "duration": duration,
        "effects": list(case.effects),
        "seed": spec["seed"],
        "noise": case.noise,
        "sigma": case.sigma,
        "sizes": case.sizes,
        "truth": case.truth_description,
        "generate_seconds": time.perf_counter() - start,
    }
    return result, case, diagnose_key


def diagnose_cases(generated, args) -> None:
    """The cases diagnosed in one batch (`--model piezo`), each record updated."""
    if args.dry_run:
        return
    records = [
        common.BatchRecord(
            f"{i:03d}_{r['excitation']}_{_label(r['effects'])}_seed{r['seed']}",
            case.recording,
            key,
            {
                "excitation": r["excitation"],
                "truth": common.effects_label(r["effects"], none=""),
                "case_seed": str(r["seed"]),
            },
        )
        for i, (r, case, key) in enumerate(generated, start=1)
    ]
    diagnoses = common.diagnose_batch(records, {"model": "piezo"}, args)
    for (result, case, _), diagnosis in zip(generated, diagnoses, strict=True):
        data = diagnosis.json
        named = [str(f["effect"]) for f in data["findings"]]
        undecided = frozenset(data["undecided"])
        final = float(data["final"]["rmse"])
        result.update(
            named=named,
            undecided=sorted(undecided),
            advice=[
                {
                    "separates": list(a["separates"]),
                    "input": a["input"],
                    "difference_sigma": float(a["difference_sigma"]),
                }
                for a in data["advice"]
            ],
            outcome=classify(frozenset(case.effects), frozenset(named), undecided),
            final_rmse=final,
            final_over_sigma=final / case.sigma,
            seconds=diagnosis.seconds,
            wall_seconds=diagnosis.wall_seconds,
        )


def totals(results) -> dict[str, dict[str, int]]:
    """Per excitation (and "all"): cases and the count of each class."""
    out: dict[str, dict[str, int]] = {}
    for r in results:
        for group in (r["excitation"], "all"):
            row = out.setdefault(group, {"cases": 0, **dict.fromkeys(CLASSES, 0)})
            row["cases"] += 1
            row[r["outcome"]] += 1
    return out


def headline(results) -> dict[str, Any]:
    """False claims on single-frequency records (the target: none)."""
    single = [r for r in results if r["excitation"] in SINGLE_FREQUENCY]
    claims = [r for r in single if r["outcome"] == "false claim"]
    return {
        "single_frequency_cases": len(single),
        "false_claims": len(claims),
        "false_claim_cases": [
            f"{r['excitation']} / {_label(r['effects'])} / seed {r['seed']}: named "
            f"{_label(r['named'])}"
            for r in claims
        ],
    }


def _print_case(i: int, total: int, r: dict[str, Any]) -> None:
    sizes = ", ".join(f"{k} {v:.1f}" for k, v in r["sizes"].items()) or "-"
    line = (
        f"[{i:3d}/{total}] {r['excitation']:<10} {_label(r['effects']):<16} "
        f"seed {r['seed']} sizes(sigma): {sizes:<22} gen {r['generate_seconds']:.1f}s"
    )
    if "outcome" in r:
        line += (
            f" | {r['outcome']:<11} named {_label(r['named']):<22} undecided "
            f"{_label(r['undecided']) if r['undecided'] else '-':<22} final "
            f"{r['final_over_sigma']:.2f} sigma {r['seconds']:.1f}s"
        )
    print(line, flush=True)
    for a in r.get("advice", []):
        print(
            f"        advice: {' vs '.join(a['separates'])}: {a['input']} "
            f"({a['difference_sigma']:.1f} sigma apart)",
            flush=True,
        )


def _print_totals(table: dict[str, dict[str, int]]) -> None:
    print(
        f"{'excitation':<12}{'cases':>6}{'exact':>7}{'cannot tell':>13}"
        f"{'false claims':>14}{'missed':>8}{'right':>8}"
    )
    for group, row in table.items():
        right = sum(row[c] for c in RIGHT) / row["cases"]
        print(
            f"{group:<12}{row['cases']:>6}{row['exact']:>7}{row['cannot tell']:>13}"
            f"{row['false claim']:>14}{row['missed']:>8}{right:>8.0%}"
        )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description="Diagnosis on practical piezo records: exact, cannot tell, "
        "false claims, missed."
    )
    parser.add_argument(
        "--excitations",
        nargs="+",
        choices=tuple(EXCITATIONS),
        help=f"drives to run (default all: {', '.join(EXCITATIONS)})",
    )
    parser.add_argument(
        "--effects",
        nargs="+",
        choices=EFFECT_CHOICES,
        help="concealed effects, one per case ('none': a clean record; default all)",
    )
    parser.add_argument(
        "--noise", choices=("white", "coloured"), default="white", help="(white)"
    )
    parser.add_argument(
        "--size",
        type=float,
        default=None,
        help="every effect's size in noise sigmas (default: drawn from 3-10)",
    )
    parser.add_argument("--rate", type=float, default=None, help="Hz (1000)")
    common.add_suite_options(
        parser,
        "the 1 Hz sine, no effect and creep, 500 Hz (filters and --rate still apply)",
        cases=1,
        generates="the records and print them",
    )
    args = parser.parse_args(argv)
    if args.cases < 1:
        parser.error("--cases must be >= 1")
    if args.size is not None and not args.size > 0:
        parser.error("--size must be a positive number of noise sigmas")
    quick = QUICK if args.quick else (tuple(EXCITATIONS), EFFECT_CHOICES, 1000.0)
    excitations = tuple(args.excitations or quick[0])
    effects = tuple(args.effects or quick[1])
    args.rate = quick[2] if args.rate is None else args.rate

    specs = build_cases(excitations, effects, args.cases)
    env = common.machine_info()
    print(
        f"practical records: {len(specs)} cases ({', '.join(excitations)}) at "
        f"{args.rate:g} Hz, {args.noise} noise; jax {env['versions']['jax']} on "
        f"{env['devices']}, jaxhyst {env['versions']['jaxhyst']}"
    )
    generated = [generate_case(spec, args) for spec in specs]
    diagnose_cases(generated, args)
    results = [r for r, _, _ in generated]
    for i, r in enumerate(results, start=1):
        _print_case(i, len(specs), r)

    config = {
        "excitations": {
            name: {"input": drive.describe(), "duration": duration}
            for name, (drive, duration) in EXCITATIONS.items()
            if name in excitations
        },
        "effects": list(effects),
        "cases_per_configuration": args.cases,
        "rate": args.rate,
        "noise": args.noise,
        "size_sigmas": args.size,
        "seed": args.seed,
        "quick": args.quick,
        "dry_run": args.dry_run,
        "workers": args.workers,
    }
    report = common.suite_report(config, env, results)
    if not args.dry_run:
        table = totals(results)
        head = headline(results)
        report["totals"] = table
        report["headline"] = head
        report["median_seconds"] = statistics.median(r["seconds"] for r in results)
        report["median_final_over_sigma"] = float(
            np.median([r["final_over_sigma"] for r in results])
        )
        print()
        _print_totals(table)
        print()
        print(
            f"false claims on single-frequency records: {head['false_claims']} of "
            f"{head['single_frequency_cases']} cases"
            + (" (target: none)" if head["false_claims"] else "")
        )
        for line in head["false_claim_cases"]:
            print(f"  {line}")
        print(
            f"median seconds per recording: {report['median_seconds']:.1f}; median "
            f"final RMSE {report['median_final_over_sigma']:.2f} sigma"
        )
    return common.finish_suite(report, args.json)


if __name__ == "__main__":
    sys.exit(main())
