"""Benchmark: does the diagnosis find concealed effects, and only those?

Runs `jaxhyst.diagnose` on the synthetic suite of `jaxhyst.concealed_recording`:
each of the six effects alone under white and coloured noise, a few pairs, and clean
records (white and coloured) where nothing may be flagged; every case with `--cases`
seeds. The truth is written in forms that differ from the diagnosis catalogue's
equations (see `jaxhyst/_synthetic.py`), and each effect changes the output by only
3-10 noise sigmas.

Reports
- exact-set accuracy on the effect cases (the named set equals the concealed set),
- the no-finding rate on the clean cases,
- the fraction of cases whose final residual RMS is <= 1.3 sigma (the true sigma),
- the median seconds per recording (the diagnosis only; generation is reported
  separately),
- a confusion matrix: rows the true effect (a pair counts in both rows; "none" for
  clean records), columns the named effect ("none" when nothing was named).

    python benchmarks/concealed_effects.py                # 45 s at 1 kHz, 3 seeds
    python benchmarks/concealed_effects.py --quick        # a smoke run
    python benchmarks/concealed_effects.py --dry-run      # generate only
    python benchmarks/concealed_effects.py --json out.json
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


EFFECTS = (
    "asymmetry",
    "input_bias",
    "rate_dependence",
    "creep",
    "dynamics",
    "drift",
)
PAIRS = (
    ("asymmetry", "input_bias"),
    ("creep", "drift"),
    ("asymmetry", "dynamics"),
)
NOISES = ("white", "coloured")
RESIDUAL_FACTOR = 1.3


def _diagnose_function():
    """`jaxhyst.diagnose`, imported lazily: the diagnosis may not exist yet."""
    diagnose = getattr(jh, "diagnose", None)
    if diagnose is None:
        raise SystemExit(
            "concealed_effects: jaxhyst.diagnose is not available in this checkout "
            "(the diagnosis API, jh.diagnose(recording, *, key, model=None, "
            "progress=False) -> Diagnosis, is not there yet). Run with --dry-run to "
            "exercise the synthetic suite alone."
        )
    return diagnose


def build_cases(seeds: int, noises: tuple[str, ...]) -> list[dict[str, Any]]:
    """The suite: singles and pairs under each noise, and clean records (twice the
    seeds, since a false-alarm rate needs more cases)."""
    cases = []
    for effect in EFFECTS:
        for noise in noises:
            cases += [
                {"effects": (effect,), "noise": noise, "seed": s} for s in range(seeds)
            ]
    for pair in PAIRS:
        for noise in noises:
            cases += [
                {"effects": pair, "noise": noise, "seed": s} for s in range(seeds)
            ]
    for noise in NOISES:
        cases += [{"effects": (), "noise": noise, "seed": s} for s in range(2 * seeds)]
    return cases


def _case_keys(root: int, index: int):
    key = jax.random.fold_in(jax.random.key(root), index)
    return jax.random.split(key)


def _label(effects) -> str:
    return "+".join(effects) if effects else "clean"


def run_case(spec, index, args, diagnose) -> dict[str, Any]:
    generate_key, diagnose_key = _case_keys(args.seed, index)
    start = time.perf_counter()
    case = jh.concealed_recording(
        spec["effects"],
        key=generate_key,
        duration=args.duration,
        rate=args.rate,
        noise=spec["noise"],
    )
    generated = time.perf_counter() - start
    result: dict[str, Any] = {
        "index": index,
        "effects": list(case.effects),
        "noise": case.noise,
        "seed": spec["seed"],
        "sigma": case.sigma,
        "sizes": case.sizes,
        "truth": case.truth_description,
        "generate_seconds": generated,
    }
    if diagnose is None:
        return result
    start = time.perf_counter()
    diagnosis = diagnose(case.recording, key=diagnose_key, progress=args.progress)
    wall = time.perf_counter() - start
    named = [str(f.effect) for f in diagnosis.findings]
    seconds = getattr(diagnosis, "seconds", None)
    final = float(diagnosis.final_rmse)
    result.update(
        named=named,
        exact=set(named) == set(case.effects),
        # Effects the diagnosis says this record cannot decide on.
        undecided=sorted(diagnosis.undecided),
        decided=all(f.decided for f in diagnosis.findings),
        final_rmse=final,
        final_over_sigma=final / case.sigma,
        noise_sigma_estimate=float(getattr(diagnosis, "noise_sigma", math.nan)),
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
    summary = {
        "cases": len(results),
        "exact_set_accuracy": mean([r["exact"] for r in effect_cases]),
        "true_effect_recall": mean(
            [e in r["named"] for r in effect_cases for e in r["effects"]]
        ),
        "clean_no_finding_rate": mean([not r["named"] for r in clean_cases]),
        "final_within_1.3_sigma": mean(
            [r["final_over_sigma"] <= RESIDUAL_FACTOR for r in results]
        ),
        "median_final_over_sigma": float(
            np.median([r["final_over_sigma"] for r in results])
        ),
        "median_seconds": statistics.median(r["seconds"] for r in results),
        "by_configuration": {},
    }
    groups: dict[str, list] = {}
    for r in results:
        groups.setdefault(f"{_label(r['effects'])} / {r['noise']}", []).append(r)
    for name, group in groups.items():
        summary["by_configuration"][name] = {
            "cases": len(group),
            "exact": mean([r["exact"] for r in group]),
            "median_final_over_sigma": float(
                np.median([r["final_over_sigma"] for r in group])
            ),
        }
    return summary


def _print_confusion(rows, columns, table) -> None:
    short = [c[:9] for c in columns]
    width = max(len(r) for r in rows) + 2
    print("confusion (rows: true effect, columns: named effect)")
    print(" " * width + " ".join(f"{c:>9}" for c in short))
    for row, counts in zip(rows, table):
        print(f"{row:<{width}}" + " ".join(f"{n:>9d}" for n in counts))


def environment() -> dict[str, Any]:
    return {
        "python": platform.python_version(),
        "platform": platform.platform(),
        "jax": jax.__version__,
        "jaxhyst": jh.__version__,
        "devices": [str(d) for d in jax.devices()],
        "x64": bool(jax.config.read("jax_enable_x64")),
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--cases", type=int, default=None, help="seeds per configuration (default 3)"
    )
    parser.add_argument("--duration", type=float, default=None, help="seconds (45)")
    parser.add_argument("--rate", type=float, default=None, help="Hz (1000)")
    parser.add_argument("--json", metavar="PATH", help="write the results here")
    parser.add_argument(
        "--quick",
        action="store_true",
        help="smoke run: 1 seed, 12 s at 500 Hz, white noise only for effect cases",
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
        help="run only these configurations (e.g. creep+drift clean asymmetry); each "
        "keeps the index, so the seed, it has in the whole suite",
    )
    args = parser.parse_args(argv)
    defaults = (1, 12.0, 500.0) if args.quick else (3, 45.0, 1000.0)
    args.cases = defaults[0] if args.cases is None else args.cases
    args.duration = defaults[1] if args.duration is None else args.duration
    args.rate = defaults[2] if args.rate is None else args.rate
    if args.cases < 1:
        parser.error("--cases must be >= 1")

    diagnose = None if args.dry_run else _diagnose_function()
    specs = build_cases(args.cases, ("white",) if args.quick else NOISES)
    env = environment()
    print(
        f"concealed effects: {len(specs)} cases, {args.duration:g} s at "
        f"{args.rate:g} Hz; jax {env['jax']} on {env['devices']}, jaxhyst "
        f"{env['jaxhyst']}"
    )
    results = []
    for index, spec in enumerate(specs):
        if args.only and _label(spec["effects"]) not in args.only:
            continue
        r = run_case(spec, index, args, diagnose)
        results.append(r)
        sizes = ", ".join(f"{k} {v:.1f}" for k, v in r["sizes"].items()) or "-"
        line = (
            f"[{index + 1:3d}/{len(specs)}] {_label(r['effects']):<26} "
            f"{r['noise']:<8} sizes(sigma): {sizes:<34} gen {r['generate_seconds']:.1f}s"
        )
        if diagnose is not None:
            named = "+".join(r["named"]) or "none"
            mark = "ok " if r["exact"] else "MISS"
            line += (
                f" | {mark} named {named:<26} final {r['final_over_sigma']:.2f} sigma "
                f"{r['seconds']:.1f}s"
            )
        print(line, flush=True)

    report: dict[str, Any] = {
        "config": {
            "cases_per_configuration": args.cases,
            "duration": args.duration,
            "rate": args.rate,
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
        print(f"true-effect recall:                {summary['true_effect_recall']:.1%}")
        print(
            f"clean cases with no finding:       {summary['clean_no_finding_rate']:.1%}"
        )
        print(
            f"final residual <= {RESIDUAL_FACTOR} sigma:       "
            f"{summary['final_within_1.3_sigma']:.1%} "
            f"(median {summary['median_final_over_sigma']:.2f} sigma)"
        )
        print(f"median seconds per recording:      {summary['median_seconds']:.1f}")
        print()
        _print_confusion(rows, columns, table)
    print(
        f"median generation seconds per recording: "
        f"{report['generate_median_seconds']:.2f}"
    )
    if args.json:
        with open(args.json, "w") as file:
            json.dump(report, file, indent=2)
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
