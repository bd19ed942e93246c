"""Benchmark: does the structural diagnosis find concealed effects, and only those?

Runs `jaxhyst.diagnose(..., family=jaxhyst.StructuralFamily())` on the synthetic
structural suite (`jaxhyst._synthetic_structural.structural_recording`): quasi-static
tests of a Bouc-Wen element (x in mm, F in kN, pseudo time t = sample index) with
each of the four effects alone under white and coloured noise, the pairs
(degradation, pinching) [the common one in real tests], (degradation, asymmetry) and
(pinching, drift), and clean records (white and coloured, twice the seeds) where
nothing may be named. Protocols are mixed: half the cases run the stepwise cyclic
protocol (ATC-24 / FEMA 461), half the earthquake-like history. The truth is
written in forms that differ from the catalogue's (`StructuralBoucWen`), and each
effect changes the force by only 4-12 noise sigmas.

Reports
- exact-set accuracy on the effect cases (the named set equals the concealed set),
- the no-finding rate on the clean cases,
- the fraction of effect cases whose final residual RMS is <= 1.3 sigma (the true
  sigma),
- the median seconds per recording (the diagnosis only; generation is reported
  separately),
- a confusion matrix: rows the true effect (a pair counts in both rows; "none" for
  clean records), columns the named effect ("none" when nothing was named).

    python benchmarks/structural_suite.py                 # 2000 points, 3 seeds
    python benchmarks/structural_suite.py --quick         # a smoke run
    python benchmarks/structural_suite.py --dry-run       # generate only
    python benchmarks/structural_suite.py --json out.json
"""

import argparse
import json
import math
import platform
import statistics
import sys
import time
from collections import Counter
from typing import Any

import jax


jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

import jaxhyst as jh  # noqa: E402
from jaxhyst._synthetic_structural import structural_recording  # noqa: E402


EFFECTS = ("degradation", "pinching", "asymmetry", "drift")
PAIRS = (
    ("degradation", "pinching"),
    ("degradation", "asymmetry"),
    ("pinching", "drift"),
)
NOISES = ("white", "coloured")
PROTOCOLS = ("cyclic", "earthquake")
RESIDUAL_FACTOR = 1.3


def _diagnose_function():
    """`jaxhyst.diagnose` and `jaxhyst.StructuralFamily`, looked up lazily: the
    structural diagnosis may not exist yet in this checkout."""
    diagnose = getattr(jh, "diagnose", None)
    family = getattr(jh, "StructuralFamily", None)
    if diagnose is None or family is None:
        missing = [
            name
            for name, found in (("diagnose", diagnose), ("StructuralFamily", family))
            if found is None
        ]
        raise SystemExit(
            f"structural_suite: jaxhyst.{' and jaxhyst.'.join(missing)} not available "
            "in this checkout (the structural diagnosis, jh.diagnose(recording, *, "
            "key, family=jh.StructuralFamily()) -> Diagnosis, is not there yet). Run "
            "with --dry-run to exercise the synthetic suite alone."
        )
    return diagnose, family


def build_cases(seeds: int, noises: tuple[str, ...]) -> list[dict[str, Any]]:
    """The suite: singles and pairs under each noise, and clean records (twice the
    seeds, since a false-alarm rate needs more cases). Protocols alternate with the
    seed, the noise and the configuration, so that even one seed mixes them."""
    cases = []
    groups = [*((e,) for e in EFFECTS), *PAIRS]
    for g, group in enumerate(groups):
        for m, noise in enumerate(noises):
            cases += [
                {
                    "effects": group,
                    "noise": noise,
                    "seed": s,
                    "protocol": PROTOCOLS[(s + m + g) % len(PROTOCOLS)],
                }
                for s in range(seeds)
            ]
    for m, noise in enumerate(NOISES):
        cases += [
            {
                "effects": (),
                "noise": noise,
                "seed": s,
                "protocol": PROTOCOLS[(s + m) % len(PROTOCOLS)],
            }
            for s in range(2 * seeds)
        ]
    return cases


def _case_keys(root: int, index: int):
    key = jax.random.fold_in(jax.random.key(root), index)
    return jax.random.split(key)


def _label(effects) -> str:
    return "+".join(effects) if effects else "clean"


def run_case(spec, index, args, diagnose, family) -> dict[str, Any]:
    generate_key, diagnose_key = _case_keys(args.seed, index)
    start = time.perf_counter()
    case = structural_recording(
        spec["effects"],
        key=generate_key,
        noise=spec["noise"],
        protocol=spec["protocol"],
        points=args.points,
    )
    generated = time.perf_counter() - start
    result: dict[str, Any] = {
        "index": index,
        "effects": list(case.effects),
        "noise": case.noise,
        "protocol": case.protocol,
        "seed": spec["seed"],
        "sigma": case.sigma,
        "sizes": case.sizes,
        "forms": case.forms,
        "truth": case.truth_description,
        "generate_seconds": generated,
    }
    if diagnose is None:
        return result
    options = {"progress": True} if args.progress else {}
    start = time.perf_counter()
    diagnosis = diagnose(case.recording, key=diagnose_key, family=family(), **options)
    wall = time.perf_counter() - start
    named = [str(f.effect) for f in diagnosis.findings]
    seconds = getattr(diagnosis, "seconds", None)
    final = float(diagnosis.final_rmse)
    result.update(
        named=named,
        exact=set(named) == set(case.effects),
        final_rmse=final,
        final_over_sigma=final / case.sigma,
        unexplained=[str(u) for u in getattr(diagnosis, "unexplained", [])],
        seconds=float(seconds) if seconds is not None else wall,
        wall_seconds=wall,
    )
    return result


def confusion(results) -> tuple[list[str], list[str], list[list[int]]]:
    rows = [*EFFECTS, "none"]
    named = {n for r in results for n in r["named"]}
    columns = [*EFFECTS, *sorted(named - set(EFFECTS)), "none"]
    counts: Counter = Counter()
    for r in results:
        truth = r["effects"] or ["none"]
        guesses = r["named"] or ["none"]
        for t in truth:
            for g in guesses:
                counts[t, g] += 1
    return rows, columns, [[counts[r, c] for c in columns] for r in rows]


def summarise(results) -> dict[str, Any]:
    effect_cases = [r for r in results if r["effects"]]
    clean_cases = [r for r in results if not r["effects"]]
    mean = lambda xs: float(np.mean(xs)) if xs else math.nan
    median = lambda xs: float(np.median(xs)) if xs else math.nan
    summary = {
        "cases": len(results),
        "exact_set_accuracy": mean([r["exact"] for r in effect_cases]),
        "true_effect_recall": mean(
            [e in r["named"] for r in effect_cases for e in r["effects"]]
        ),
        "clean_no_finding_rate": mean([not r["named"] for r in clean_cases]),
        "final_within_1.3_sigma": mean(
            [r["final_over_sigma"] <= RESIDUAL_FACTOR for r in effect_cases]
        ),
        "median_final_over_sigma": median([r["final_over_sigma"] for r in results]),
        "median_seconds": statistics.median(r["seconds"] for r in results),
        "by_configuration": {},
        "by_protocol": {},
    }
    groups: dict[str, list] = {}
    for r in results:
        groups.setdefault(f"{_label(r['effects'])} / {r['noise']}", []).append(r)
    for name, group in groups.items():
        summary["by_configuration"][name] = {
            "cases": len(group),
            "exact": mean([r["exact"] for r in group]),
            "median_final_over_sigma": median([r["final_over_sigma"] for r in group]),
        }
    for protocol in PROTOCOLS:
        group = [r for r in effect_cases if r["protocol"] == protocol]
        summary["by_protocol"][protocol] = {
            "effect_cases": len(group),
            "exact": mean([r["exact"] for r in group]),
        }
    return summary


def _print_confusion(rows, columns, table) -> None:
    short = [c[:11] for c in columns]
    width = max(len(r) for r in rows) + 2
    print("confusion (rows: true effect, columns: named effect)")
    print(" " * width + " ".join(f"{c:>11}" for c in short))
    for row, counts in zip(rows, table):
        print(f"{row:<{width}}" + " ".join(f"{n:>11d}" for n in counts))


def environment() -> dict[str, Any]:
    return {
        "python": platform.python_version(),
        "platform": platform.platform(),
        "machine": platform.machine(),
        "processor": platform.processor(),
        "jax": jax.__version__,
        "numpy": np.__version__,
        "jaxhyst": jh.__version__,
        "devices": [str(d) for d in jax.devices()],
        "x64": bool(jax.config.read("jax_enable_x64")),
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--cases", type=int, default=None, help="seeds per configuration (default 3)"
    )
    parser.add_argument(
        "--points", type=int, default=None, help="samples per record (2000)"
    )
    parser.add_argument("--json", metavar="PATH", help="write the results here")
    parser.add_argument(
        "--quick",
        action="store_true",
        help="smoke run: 1 seed, 1000 points, white noise only for effect cases",
    )
    parser.add_argument("--seed", type=int, default=0, help="root seed (0)")
    parser.add_argument(
        "--dry-run",
        action="store_true",
        help="generate the suite and print it, without diagnosing",
    )
    parser.add_argument(
        "--progress", action="store_true", help="pass progress=True to diagnose"
    )
    parser.add_argument(
        "--only",
        nargs="+",
        metavar="LABEL",
        help="run only these configurations (e.g. degradation+pinching clean drift); "
        "each keeps the index, so the seed, it has in the whole suite",
    )
    args = parser.parse_args(argv)
    defaults = (1, 1000) if args.quick else (3, 2000)
    args.cases = defaults[0] if args.cases is None else args.cases
    args.points = defaults[1] if args.points is None else args.points
    if args.cases < 1:
        parser.error("--cases must be >= 1")

    diagnose, family = (None, None) if args.dry_run else _diagnose_function()
    specs = build_cases(args.cases, ("white",) if args.quick else NOISES)
    env = environment()
    print(
        f"structural suite: {len(specs)} cases, {args.points} points each; python "
        f"{env['python']} on {env['platform']} ({env['machine']}), jax {env['jax']} "
        f"on {env['devices']}, numpy {env['numpy']}, jaxhyst {env['jaxhyst']}"
    )
    results = []
    for index, spec in enumerate(specs):
        if args.only and _label(spec["effects"]) not in args.only:
            continue
        r = run_case(spec, index, args, diagnose, family)
        results.append(r)
        sizes = (
            ", ".join(f"{k} {v:.1f} {r['forms'][k]}" for k, v in r["sizes"].items())
            or "-"
        )
        line = (
            f"[{index + 1:3d}/{len(specs)}] {_label(r['effects']):<22} "
            f"{r['noise']:<8} {r['protocol']:<10} sizes(sigma): {sizes:<44} "
            f"gen {r['generate_seconds']:.2f}s"
        )
        if diagnose is not None:
            named = "+".join(r["named"]) or "none"
            mark = "ok " if r["exact"] else "MISS"
            line += (
                f" | {mark} named {named:<22} final {r['final_over_sigma']:.2f} sigma "
                f"{r['seconds']:.1f}s"
            )
        print(line, flush=True)
    if not results:
        print("no case matched --only")
        return 1

    report: dict[str, Any] = {
        "config": {
            "cases_per_configuration": args.cases,
            "points": args.points,
            "seed": args.seed,
            "quick": args.quick,
            "dry_run": args.dry_run,
        },
        "environment": env,
        "generate_median_seconds": statistics.median(
            r["generate_seconds"] for r in results
        ),
        "cases": results,
    }
    if diagnose is not None:
        summary = summarise(results)
        rows, columns, table = confusion(results)
        report["summary"] = summary
        report["confusion"] = {"rows": rows, "columns": columns, "counts": table}
        print()
        print(f"exact-set accuracy (effect cases): {summary['exact_set_accuracy']:.1%}")
        for protocol, part in summary["by_protocol"].items():
            print(f"  {protocol:<10} {part['exact']:.1%} of {part['effect_cases']}")
        print(f"true-effect recall:                {summary['true_effect_recall']:.1%}")
        print(
            f"clean cases with no finding:       {summary['clean_no_finding_rate']:.1%}"
        )
        print(
            f"final residual <= {RESIDUAL_FACTOR} sigma (effect cases): "
            f"{summary['final_within_1.3_sigma']:.1%} "
            f"(median {summary['median_final_over_sigma']:.2f} sigma, all cases)"
        )
        print(f"median seconds per recording:      {summary['median_seconds']:.1f}")
        print()
        _print_confusion(rows, columns, table)
    print(
        f"median generation seconds per recording: "
        f"{report['generate_median_seconds']:.2f} (the first includes compilation)"
    )
    if args.json:
        with open(args.json, "w") as file:
            json.dump(report, file, indent=2)
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
