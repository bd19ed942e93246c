"""Benchmark: does the structural diagnosis find concealed effects, and only those?

Runs `jaxhyst diagnose --model bouc-wen` (the family `StructuralFamily()`) on the
synthetic structural suite (`jaxhyst.synthetic.structural_recording`): quasi-static
tests of a Bouc-Wen element (x in mm, F in kN, pseudo time t = sample index) with
each of the four effects alone under white and coloured noise, the pairs
(degradation, pinching) [the common one in real tests], (degradation, asymmetry) and
(pinching, drift), and clean records (white and coloured, twice the seeds) where
nothing may be named. Protocols are mixed: half the cases run the stepwise cyclic
protocol (ATC-24 / FEMA 461), half the earthquake-like history. The truth is
written in forms that differ from the catalogue's (`StructuralBoucWen`), and each
effect changes the force by only 4-12 noise sigmas. The records are diagnosed in one
`jh.batch` (CSV files and a manifest, each record's diagnosis key as its `seed`) on
`--workers` workers of one thread (2); `--out DIR` keeps the batch folder.

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
import sys
import time
from typing import Any

import jax


jax.config.update("jax_enable_x64", True)

import _common as common  # noqa: E402

from jaxhyst.synthetic import structural_recording  # noqa: E402


EFFECTS = ("degradation", "pinching", "asymmetry", "drift")
PAIRS = (
    ("degradation", "pinching"),
    ("degradation", "asymmetry"),
    ("pinching", "drift"),
)
NOISES = ("white", "coloured")
PROTOCOLS = ("cyclic", "earthquake")
RESIDUAL_FACTOR = 1.3


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


def generate_case(spec, index, args) -> tuple[dict[str, Any], Any, Any]:
    """Case `index`'s record, its recording and its diagnosis key."""
    generate_key, diagnose_key = common.case_keys(args.seed, index)
    start = time.perf_counter()
    case = structural_recording(
        spec["effects"],
        key=generate_key,
        noise=spec["noise"],
        protocol=spec["protocol"],
        points=args.points,
    )
    generated = time.perf_counter() - start
    result = common.case_record(
        index, spec, case, generated, protocol=case.protocol, forms=case.forms
    )
    return result, case, diagnose_key


def summarise(report: dict) -> dict[str, Any]:
    """`score_suite`'s summary (the residual over the effect cases), with the exact-set
    accuracy per protocol."""
    summary = common.score_suite(
        report, EFFECTS, RESIDUAL_FACTOR, effect_cases_only=True
    )
    effect_cases = [r for r in report["cases"] if r["effects"]]
    summary["by_protocol"] = {}
    for protocol in PROTOCOLS:
        group = [r for r in effect_cases if r["protocol"] == protocol]
        summary["by_protocol"][protocol] = {
            "effect_cases": len(group),
            "exact": common.mean_or_nan([r["exact"] for r in group]),
        }
    return summary


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    common.add_suite_options(
        parser,
        "1 seed, 1000 points, white noise only for effect cases",
        only_example="degradation+pinching clean drift",
    )
    parser.add_argument(
        "--points", type=int, default=None, help="samples per record (2000)"
    )
    args = parser.parse_args(argv)
    defaults = (1, 1000) if args.quick else (3, 2000)
    args.cases = defaults[0] if args.cases is None else args.cases
    args.points = defaults[1] if args.points is None else args.points
    if args.cases < 1:
        parser.error("--cases must be >= 1")

    specs = build_cases(args.cases, ("white",) if args.quick else NOISES)
    env = common.machine_info()
    versions = env["versions"]
    print(
        f"structural suite: {len(specs)} cases, {args.points} points each; python "
        f"{env['python']} on {env['platform']} ({env['cpu_model']}), jax "
        f"{versions['jax']} on {env['devices']}, numpy {versions['numpy']}, jaxhyst "
        f"{versions['jaxhyst']}"
    )
    generated = [
        generate_case(spec, index, args)
        for index, spec in common.selected(specs, args.only)
    ]
    if not generated:
        print("no case matched --only")
        return 1
    # The structural family is `diagnose --model bouc-wen`.
    common.diagnose_suite(args, "bouc-wen", generated)
    results = [r for r, _, _ in generated]
    for r in results:
        line = common.case_line(
            r["index"],
            len(specs),
            r,
            width=22,
            sizes_width=44,
            extra=f"{r['protocol']:<10} ",
        )
        print(line, flush=True)

    config = common.suite_config(args, points=args.points)
    report = common.suite_report(config, env, results)
    if not args.dry_run:
        summary = summarise(report)
        common.print_summary(
            summary, report, RESIDUAL_FACTOR, width=11, over="effect cases"
        )
    return common.finish_suite(report, args.json, " (the first includes compilation)")


if __name__ == "__main__":
    sys.exit(main())
