"""How long a user waits for `jaxhyst diagnose` on a 45 000-sample record: a fresh
process per run, with an empty and then a warm cache.

For each of `--cases` concealed-effect records (`jh.synthetic.concealed_recording`,
white noise, 45 s at 1 kHz; the effects in turn: asymmetry, input_bias,
rate_dependence, creep, dynamics, drift, then a clean record), written to a CSV
file as a user's recording would be: `jaxhyst diagnose RECORD.csv --json OUT --seed
S` in a fresh process with `JAXHYST_CACHE_DIR` a new empty folder (a cold start:
every program traced, compiled and written to the cache), then again in a fresh
process with the same folder (warm: the compiled programs and, since session 19,
the traced ones are read back). The parent measures each process from its start to
its exit. Reports the medians over the records, the named effects and final RMS of
each run (the warm runs must equal the cold ones), and what the cache holds. The
children cache Python bytecode, as a user's Python does (`--no-bytecode-cache`:
every module compiled from source in each process, as with PYTHONDONTWRITEBYTECODE).

    python benchmarks/diagnose_speed.py                 # 5 records (~8 min)
    python benchmarks/diagnose_speed.py --cases 1 --json out.json
    python benchmarks/diagnose_speed.py --cases 2 --baseline ../base   # ratios

With `--baseline TREE` (a checkout of an earlier commit) each record is also
diagnosed by that tree's `python -m jaxhyst diagnose`, cold then warm in its own
cache folder, right after this tree's (both through `python -m jaxhyst`), and this
tree's medians are given as ratios of the baseline's. The two trees may name
different effects (the engine may have changed between them): both are printed.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import _common as common


CASES = (
    ("asymmetry",),
    ("input_bias",),
    ("rate_dependence",),
    ("creep",),
    ("dynamics",),
    ("drift",),
    (),
)


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument(
        "--cases", type=int, default=5, help=f"records, 1-{len(CASES)} (5)"
    )
    parser.add_argument("--duration", type=float, default=45.0, help="seconds (45)")
    parser.add_argument("--rate", type=float, default=1000.0, help="Hz (1000)")
    parser.add_argument("--seed", type=int, default=0, help="records and diagnosis")
    common.add_baseline(parser)
    common.add_bytecode(parser)
    common.add_json(parser)
    args = parser.parse_args(argv)
    if not 1 <= args.cases <= len(CASES):
        parser.error(f"--cases must be between 1 and {len(CASES)}")
    return args


def write_records(args, folder: str) -> list[str]:
    import jax

    jax.config.update("jax_enable_x64", True)
    import jaxhyst as jh

    paths = []
    for index, effects in enumerate(CASES[: args.cases]):
        generate, _ = common.case_keys(args.seed, index)
        case = jh.synthetic.concealed_recording(
            effects,
            key=generate,
            duration=args.duration,
            rate=args.rate,
            noise="white",
        )
        path = os.path.join(folder, f"{common.effects_label(effects)}.csv")
        case.recording.save(path)
        paths.append(path)
    return paths


def run_diagnose(
    record: str,
    cache: str,
    out: str,
    seed: int,
    pycache: str | None,
    tree: str | None,
    launcher: list[str],
) -> dict:
    command = [*launcher, "diagnose", record, "--json", out, "--force"]
    command += ["--seed", str(seed)]
    env = common.from_tree(
        common.child_environment(pycache, JAXHYST_CACHE_DIR=cache), tree
    )
    start = time.perf_counter()
    done = subprocess.run(command, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{done.stderr[-3000:]}")
    with open(out) as f:
        result = json.load(f)
    entries, size = common.cache_size(cache)
    programs = os.path.join(cache, "programs")
    return {
        "wall_s": wall,
        "named": [finding["effect"] for finding in result["findings"]],
        "final_rmse": result["final"]["rmse"],
        "diagnosis_s": result["timing"]["total_s"],
        "cache_entries": entries,
        "cache_bytes": size,
        "stored_programs": len(os.listdir(programs)) if os.path.isdir(programs) else 0,
    }


def diagnose_cold_warm(args, folder, record, index, tree, label, pycache) -> dict:
    """One record diagnosed by one tree: a fresh cache folder, cold then warm."""
    cache = os.path.join(folder, f"cache-{index}-{label}")
    os.mkdir(cache)
    row = {"record": os.path.basename(record)}
    for state in ("empty", "warm"):
        common.log(f"{row['record']}: {label}: jaxhyst diagnose, {state} cache")
        out = os.path.join(folder, f"diagnosis-{index}-{label}-{state}.json")
        row[state] = run_diagnose(
            record, cache, out, args.seed, pycache, tree, common.launcher(args.baseline)
        )
    row["warm_equals_cold"] = all(
        row["warm"][k] == row["empty"][k] for k in ("named", "final_rmse")
    )
    print(
        f"{row['record']:<18} {label:<10} empty {row['empty']['wall_s']:6.1f} s, "
        f"warm {row['warm']['wall_s']:6.1f} s; named {row['warm']['named']}; "
        f"warm = cold: {row['warm_equals_cold']}",
        flush=True,
    )
    return row


def main(argv=None) -> int:
    args = parse_args(argv)
    machine = common.machine_info(devices=False, load=True)
    trees = {"this": None}
    if args.baseline:
        trees["baseline"] = args.baseline
    runs = {label: [] for label in trees}
    with tempfile.TemporaryDirectory() as folder:
        pycache = None if args.no_bytecode_cache else os.path.join(folder, "pyc")
        machine["bytecode_cached"] = pycache is not None
        if pycache is not None:
            for tree in trees.values():
                common.warm_bytecode(
                    common.from_tree(common.child_environment(pycache), tree)
                )
        records = write_records(args, folder)
        for index, record in enumerate(records):
            for label, tree in trees.items():
                runs[label].append(
                    diagnose_cold_warm(
                        args, folder, record, index, tree, label, pycache
                    )
                )
    summary = {
        label: {
            state: common.median_or_nan([r[state]["wall_s"] for r in rows])
            for state in ("empty", "warm")
        }
        for label, rows in runs.items()
    }
    common.print_machine(machine)
    for label, rows in runs.items():
        print(
            f"{label}: jaxhyst diagnose, fresh process start -> exit, {args.cases} "
            f"records of {args.duration:g} s at {args.rate:g} Hz: median "
            f"{summary[label]['empty']:.1f} s with an empty cache, "
            f"{summary[label]['warm']:.1f} s warm; warm results equal the cold ones "
            f"on {sum(r['warm_equals_cold'] for r in rows)}/{len(rows)}"
        )
    ratio = None
    if args.baseline:
        ratio = {
            state: summary["this"][state] / summary["baseline"][state]
            for state in ("empty", "warm")
        }
        print(
            f"this tree / baseline ({os.path.abspath(args.baseline)}): empty "
            f"{ratio['empty']:.2f}x, warm {ratio['warm']:.2f}x"
        )
    if args.json:
        common.write_json(
            {
                "config": vars(args),
                "machine": machine,
                "runs": runs["this"],
                "median_wall_s": summary["this"],
                "baseline": None
                if not args.baseline
                else {
                    "tree": os.path.abspath(args.baseline),
                    "runs": runs["baseline"],
                    "median_wall_s": summary["baseline"],
                    "ratio": ratio,
                },
            },
            args.json,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
