"""Benchmark: does the MR damper diagnosis find concealed effects, and only those?

Runs `jaxhyst diagnose --model mr-damper` (the family `DamperFamily()`) on the
synthetic damper suite (`jaxhyst.synthetic.damper_recording`): white-noise characterisation
tests like Dyke's (random displacement and a random piecewise-constant command,
3004.8 Hz, x in cm, command in V, F in N) with field_dependence, rolloff, offset and
asymmetry each alone, the pairs (field_dependence, driver_lag) [a lag needs a field
dependence to lag], (field_dependence, rolloff) [Spencer et al.'s model] and
(offset, asymmetry), each under white and coloured (AR(1)) load-cell noise, and
clean records (a damper that ignores its command; white and coloured, twice the
seeds) where nothing may be named. The truth is written in forms that differ from
the catalogue's (`ExtendedDamper`: saturating-exponential or power-law field,
second-order or rate-limited driver, Spencer's dashpot with an internal spring,
a warming preload with a wandering zero, valving or side-dependent yield), and
each effect changes the force by only 4-12 noise sigmas beyond what a refit of the
base takes up to first order (where its form reaches that far: Spencer's dashpot,
with c1 >= c0/2, often does not, and the size it reached is reported). The records
are diagnosed in one `jh.batch` (CSV files and a manifest, each record's diagnosis key
as its `seed`) on `--workers` workers of one thread (2); `--out DIR` keeps the batch
folder.

Reports
- exact-set accuracy on the effect cases (the named set equals the concealed set),
- the no-finding rate on the clean cases,
- the fraction of effect cases whose final residual RMS is <= 1.3 sigma (the true
  sigma),
- the median seconds per recording (the diagnosis only: its own `timing.total_s`),
- a confusion matrix: rows the true effect (a pair counts in both rows; "none" for
  clean records), columns the named effect ("none" when nothing was named).

    python benchmarks/damper_suite.py                     # 5 s records, 3 seeds
    python benchmarks/damper_suite.py --quick             # a smoke run
    python benchmarks/damper_suite.py --shard 2/4         # every 4th case from the 2nd
    python benchmarks/damper_suite.py --json out.json
    python benchmarks/damper_suite.py --merge shard*.json --json all.json
"""

import argparse
import json
import sys
import time
from typing import Any

import jax


jax.config.update("jax_enable_x64", True)

import _common as common  # noqa: E402

import jaxhyst as jh  # noqa: E402
from jaxhyst.synthetic import damper_recording  # noqa: E402


EFFECTS = jh.families.DAMPER_EFFECT_NAMES
SINGLES = (("field_dependence",), ("rolloff",), ("offset",), ("asymmetry",))
PAIRS = (
    ("field_dependence", "driver_lag"),
    ("field_dependence", "rolloff"),
    ("offset", "asymmetry"),
)
NOISES = ("white", "coloured")
RESIDUAL_FACTOR = 1.3


def build_cases(seeds: int, noises: tuple[str, ...]) -> list[dict[str, Any]]:
    """Singles and pairs under each noise, and clean records (twice the seeds)."""
    cases = [
        {"effects": group, "noise": noise, "seed": s}
        for group in (*SINGLES, *PAIRS)
        for noise in noises
        for s in range(seeds)
    ]
    cases += [
        {"effects": (), "noise": noise, "seed": s}
        for noise in NOISES
        for s in range(2 * seeds)
    ]
    return cases


def generate_case(spec, index, args) -> tuple[dict[str, Any], Any, Any]:
    """Case `index`'s record, its recording and its diagnosis key."""
    generate_key, diagnose_key = common.case_keys(args.seed, index)
    start = time.perf_counter()
    case = damper_recording(
        spec["effects"], key=generate_key, noise=spec["noise"], duration=args.duration
    )
    generated = time.perf_counter() - start
    result = common.case_record(index, spec, case, generated, forms=case.forms)
    return result, case, diagnose_key


def parse_shard(text: str | None) -> tuple[int, int]:
    if text is None:
        return 1, 1
    try:
        part, parts = (int(v) for v in text.split("/"))
    except ValueError:
        raise SystemExit(
            f"damper_suite: --shard {text!r}: write it as I/N, e.g. 2/4"
        ) from None
    if not 1 <= part <= parts:
        raise SystemExit(f"damper_suite: --shard {text!r}: need 1 <= I <= N")
    return part, parts


def score_and_print(report: dict) -> None:
    summary = common.score_suite(
        report, EFFECTS, RESIDUAL_FACTOR, effect_cases_only=True
    )
    common.print_summary(
        summary, report, RESIDUAL_FACTOR, width=11, over="effect cases"
    )


def merge(paths: list[str], json_path: str | None) -> int:
    """Score the shards' cases as one suite."""
    reports = [json.loads(open(path).read()) for path in paths]
    cases = sorted((c for r in reports for c in r["cases"]), key=lambda c: c["index"])
    if len({c["index"] for c in cases}) != len(cases):
        raise SystemExit("damper_suite --merge: a case appears in two reports")
    report = common.suite_report(
        {**reports[0]["config"], "shard": None, "merged": paths},
        reports[0]["environment"],
        cases,
    )
    score_and_print(report)
    return common.finish_suite(report, json_path)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    common.add_suite_options(
        parser,
        "1 seed, white noise only for effect cases",
        only_example="field_dependence+driver_lag clean rolloff",
    )
    parser.add_argument(
        "--duration", type=float, default=5.0, help="seconds per record (5)"
    )
    parser.add_argument(
        "--shard",
        default=None,
        metavar="I/N",
        help="run only cases I, I+N, I+2N, ... (1-based; for parallel runs whose "
        "JSON files are merged afterwards)",
    )
    parser.add_argument(
        "--merge",
        nargs="+",
        metavar="JSON",
        help="score the cases of these --json reports (shards) together; runs nothing",
    )
    args = parser.parse_args(argv)
    if args.merge:
        return merge(args.merge, args.json)
    args.cases = (1 if args.quick else 3) if args.cases is None else args.cases
    if args.cases < 1:
        parser.error("--cases must be >= 1")
    part, parts = parse_shard(args.shard)

    specs = build_cases(args.cases, ("white",) if args.quick else NOISES)
    env = common.machine_info()
    versions = env["versions"]
    print(
        f"damper suite: {len(specs)} cases, {args.duration} s each; python "
        f"{env['python']} on {env['platform']} ({env['cpu_model']}), jax "
        f"{versions['jax']} on {env['devices']}, jaxhyst {versions['jaxhyst']}"
    )
    generated = [
        generate_case(spec, index, args)
        for index, spec in common.selected(specs, args.only)
        if index % parts == part - 1
    ]
    if not generated:
        print("no case matched --only / --shard")
        return 1
    # The damper family is `diagnose --model mr-damper`.
    common.diagnose_suite(args, "mr-damper", generated)
    results = [r for r, _, _ in generated]
    for r in results:
        line = common.case_line(r["index"], len(specs), r, width=28, sizes_width=60)
        print(line, flush=True)

    config = common.suite_config(args, duration=args.duration, shard=args.shard)
    report = common.suite_report(config, env, results)
    if not args.dry_run:
        score_and_print(report)
    return common.finish_suite(report, args.json, " (the first includes compilation)")


if __name__ == "__main__":
    sys.exit(main())
