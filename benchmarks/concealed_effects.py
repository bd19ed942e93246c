"""Benchmark: does the diagnosis find concealed effects, and only those?

Runs `jaxhyst diagnose` on the synthetic suite of `jh.synthetic.concealed_recording`:
each of the six effects alone under white and coloured noise, a few pairs, and clean
records (white and coloured) where nothing may be flagged; every case with `--cases`
seeds. The truth is written in forms that differ from the diagnosis catalogue's
equations (see `jaxhyst/synthetic/_truth.py`), and each effect changes the output by only
3-10 noise sigmas. The records are diagnosed in one `jh.batch` (CSV files and a
manifest, `--model piezo`, each record's diagnosis key as its `seed`) on `--workers`
workers of one thread (2); `--out DIR` keeps the batch folder.

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
    python benchmarks/concealed_effects.py --quick --out runs/concealed  # keep it
"""

import argparse
import math
import sys
import time
from typing import Any

import jax


jax.config.update("jax_enable_x64", True)

import _common as common  # noqa: E402

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


def generate_case(spec, index, args) -> tuple[dict[str, Any], Any, Any]:
    """Case `index`'s record, its recording and its diagnosis key."""
    generate_key, diagnose_key = common.case_keys(args.seed, index)
    start = time.perf_counter()
    case = jh.synthetic.concealed_recording(
        spec["effects"],
        key=generate_key,
        duration=args.duration,
        rate=args.rate,
        noise=spec["noise"],
    )
    generated = time.perf_counter() - start
    return common.case_record(index, spec, case, generated), case, diagnose_key


def diagnose_cases(generated, args) -> None:
    """The cases diagnosed in one batch (`--model piezo`), each record updated
    (nothing on --dry-run)."""
    if args.dry_run:
        return
    diagnoses = common.diagnose_suite(args, "piezo", generated)
    for (result, _, _), diagnosis in zip(generated, diagnoses, strict=True):
        data = diagnosis.json
        result.update(
            # Effects the diagnosis says this record cannot decide on.
            undecided=sorted(data["undecided"]),
            decided=all(f["decided"] for f in data["findings"]),
            noise_sigma_estimate=float(data["noise"].get("sigma", math.nan)),
        )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    common.add_suite_options(
        parser,
        "1 seed, 12 s at 500 Hz, white noise only for effect cases",
        only_example="creep+drift clean asymmetry",
    )
    parser.add_argument("--duration", type=float, default=None, help="seconds (45)")
    parser.add_argument("--rate", type=float, default=None, help="Hz (1000)")
    args = parser.parse_args(argv)
    defaults = (1, 12.0, 500.0) if args.quick else (3, 45.0, 1000.0)
    args.cases = defaults[0] if args.cases is None else args.cases
    args.duration = defaults[1] if args.duration is None else args.duration
    args.rate = defaults[2] if args.rate is None else args.rate
    if args.cases < 1:
        parser.error("--cases must be >= 1")

    specs = build_cases(args.cases, ("white",) if args.quick else NOISES)
    env = common.machine_info()
    print(
        f"concealed effects: {len(specs)} cases, {args.duration:g} s at "
        f"{args.rate:g} Hz; jax {env['versions']['jax']} on {env['devices']}, jaxhyst "
        f"{env['versions']['jaxhyst']}"
    )
    generated = [
        generate_case(spec, index, args)
        for index, spec in common.selected(specs, args.only)
    ]
    diagnose_cases(generated, args)
    results = [r for r, _, _ in generated]
    for r in results:
        line = common.case_line(r["index"], len(specs), r, width=26, sizes_width=34)
        print(line, flush=True)

    config = common.suite_config(args, duration=args.duration, rate=args.rate)
    report = common.suite_report(config, env, results)
    if not args.dry_run:
        summary = common.score_suite(
            report, EFFECTS, RESIDUAL_FACTOR, effect_cases_only=False
        )
        common.print_summary(
            summary, report, RESIDUAL_FACTOR, width=9, over="all cases"
        )
    return common.finish_suite(report, args.json)


if __name__ == "__main__":
    sys.exit(main())
