"""Benchmark: `jaxhyst batch` on the structural records, and its scaling.

Writes the 8 real structural tests (`jaxhyst.datasets.load_structural_test`, from
../shared/data) and synthetic structural records (`jaxhyst.synthetic.
structural_recording`, effects concealed and clean) as CSV files into a temporary
folder, with a manifest (`command` diagnose, `model` bouc-wen; labels `source` and
`truth`), and runs the manifest as one batch:

1. once to fill a fresh compilation cache (the warm-up; skipped with --cold),
2. on 2 workers of 1 thread (`LocalWorkers(2, 1)`),
3. on 1 worker of 1 thread,
4. with --sequential, the same records one after another by `jaxhyst diagnose`
   (free to use both cores).

Reports the wall time of each, the scaling 2 workers against 1 (the bar: >= 1.8x)
and against the sequential runs (>= 1.2x), the overhead per record (batch wall time
x workers / records against the records' own seconds), whether every record's
findings agree between the runs, and the synthetic records' exact-set accuracy.

    python benchmarks/batch.py                 # 8 real + 16 synthetic records
    python benchmarks/batch.py --sequential    # and the one-by-one baseline
    python benchmarks/batch.py --real 1 --synthetic 8 --sequential   # a shorter run
    python benchmarks/batch.py --quick         # 2 records, tiny swarm: a smoke run
    python benchmarks/batch.py --json out.json
"""

import argparse
import contextlib
import csv
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)

import _common as common  # noqa: E402

import jaxhyst as jh  # noqa: E402
from jaxhyst._batch import read_manifest  # noqa: E402
from jaxhyst._datasets import STRUCTURAL_TESTS  # noqa: E402
from jaxhyst.synthetic import structural_recording  # noqa: E402


SYNTHETIC = (
    ("degradation",),
    ("pinching",),
    ("asymmetry",),
    ("drift",),
    ("degradation", "pinching"),
    ("degradation", "asymmetry"),
    ("pinching", "drift"),
    (),
)


def write_records(folder: Path, args) -> Path:
    """The recordings as CSV files and their manifest; returns the manifest."""
    rows = []
    real = STRUCTURAL_TESTS[: 1 if args.quick else args.real]
    for name in real:
        try:
            recording = jh.datasets.load_structural_test(name)
        except (OSError, ValueError) as error:
            common.log(f"skipping the real test {name}: {error}")
            continue
        path = folder / f"real_{name}.csv"
        recording.save(path)
        rows.append((path.name, "real", "?", recording))
    count = 1 if args.quick else args.synthetic
    for i in range(count):
        effects = SYNTHETIC[i % len(SYNTHETIC)]
        key, _ = common.case_keys(args.seed, i)
        case = structural_recording(
            effects, key=key, noise=("white", "coloured")[i // len(SYNTHETIC) % 2]
        )
        label = common.effects_label(effects, none="")
        path = folder / f"synthetic_{i:02d}_{label or 'clean'}.csv"
        case.recording.save(path)
        rows.append((path.name, "synthetic", label, case.recording))
    manifest = folder / "manifest.csv"
    swarm = ["8", "5"] if args.quick else ["", ""]
    with open(manifest, "w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(
            ["recording", "command", "model", "input", "output", "particles"]
            + ["iterations", "source", "truth"]
        )
        for name, source, truth, recording in rows:
            columns = [recording.input_names[0], recording.output_name]
            writer.writerow(
                [name, "diagnose", "bouc-wen", *columns, *swarm, source, truth]
            )
    return manifest


def run_batch(manifest: Path, out: Path, workers: int) -> tuple[float, dict]:
    start = time.perf_counter()
    result = jh.batch(
        manifest, out, cluster=jh.LocalWorkers(workers, 1), progress=False
    )
    wall = time.perf_counter() - start
    rows = {
        row.record.name: {
            "status": row.status,
            "error": row.error,
            "findings": "+".join(row.findings),
            "truth": dict(row.record.labels).get("truth", "?"),
            "seconds": row.seconds,
        }
        for row in result.rows
    }
    return wall, rows


def run_sequential(manifest: Path, folder: Path) -> tuple[float, dict]:
    """Each record by `jaxhyst diagnose` in its own process, one after another."""
    rows = {}
    start = time.perf_counter()
    for record in read_manifest(manifest).records:
        out = folder / f"{record.name}.json"
        subprocess.run(
            [*common.cli_command(), *record.argv(), "--json", str(out)],
            check=True,
            capture_output=True,
        )
        data = json.loads(out.read_text())
        rows[record.name] = {
            "findings": "+".join(f["effect"] for f in data["findings"])
        }
    return time.perf_counter() - start, rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 records, tiny swarm")
    parser.add_argument(
        "--real", type=int, default=len(STRUCTURAL_TESTS), help="the first N real tests"
    )
    parser.add_argument("--synthetic", type=int, default=16)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--cold", action="store_true", help="no warm-up batch")
    parser.add_argument("--sequential", action="store_true")
    parser.add_argument("--json", default=None)
    parser.add_argument(
        "--cache",
        default=None,
        help="the compilation cache folder to use (default: a new one in the run's "
        "folder, filled by the warm-up)",
    )
    parser.add_argument(
        "--keep",
        default=None,
        help="a new folder to keep the records, the cache and the batches' outputs in "
        "(default: a temporary folder, removed at the end)",
    )
    args = parser.parse_args(argv)
    if args.keep is not None and Path(args.keep).exists():
        parser.error(f"--keep {args.keep}: the folder exists; name a new one")
    info = common.machine_info("dask", "distributed")
    for line in common.machine_lines(info):
        print(line)
    report: dict = {"machine": info, "quick": args.quick}

    def save() -> None:
        # After every stage, so that a run stopped part-way keeps what it measured.
        if args.json:
            Path(args.json).write_text(json.dumps(report, indent=1, default=str))

    with contextlib.ExitStack() as stack:
        if args.keep is None:
            tmp = stack.enter_context(
                tempfile.TemporaryDirectory(prefix="jaxhyst-batch-")
            )
            folder = Path(tmp)
        else:
            folder = Path(args.keep)
            folder.mkdir(parents=True)
        (folder / "records").mkdir()
        os.environ["JAXHYST_CACHE_DIR"] = args.cache or str(folder / "cache")
        manifest = write_records(folder / "records", args)
        records = len(read_manifest(manifest).records)
        print(f"{records} records in {manifest}", flush=True)
        if not args.cold:
            wall, _ = run_batch(manifest, folder / "warm", 2)
            print(f"warm-up (filling the compilation cache): {wall:.1f} s", flush=True)
            report["warm_s"] = wall
            save()
        two_s, two = run_batch(manifest, folder / "two", 2)
        print(f"2 workers x 1 thread: {two_s:.1f} s", flush=True)
        report.update(two_workers_s=two_s, records=two)
        save()
        one_s, one = run_batch(manifest, folder / "one", 1)
        print(f"1 worker  x 1 thread: {one_s:.1f} s", flush=True)
        report.update(one_worker_s=one_s, one_worker_records=one)
        save()
        print(f"scaling 2 workers / 1 worker: {one_s / two_s:.2f}x (bar: >= 1.8x)")
        own = [r["seconds"] for r in one.values() if r["seconds"]]
        if own:
            overhead = (one_s - sum(own)) / len(own)
            print(
                f"overhead per record on 1 worker: {overhead:.1f} s (cluster start, "
                f"scheduling; records' own time {sum(own) / len(own):.1f} s each)"
            )
            report["overhead_per_record_s"] = overhead
        agree = all(two[n]["findings"] == one[n]["findings"] for n in two)
        print(f"findings identical on 2 workers and on 1: {agree}")
        report["findings_agree"] = agree
        synthetic = [r for r in two.values() if r["truth"] != "?"]
        if synthetic:
            exact = sum(r["findings"] == r["truth"] for r in synthetic)
            print(f"synthetic exact-set accuracy: {exact}/{len(synthetic)}")
            report["synthetic_exact"] = [exact, len(synthetic)]
        for name, row in two.items():
            error = f" ({row['error']})" if row["error"] else ""
            print(
                f"  {name}: {row['status']}{error}, found {row['findings'] or '-'} "
                f"(truth {row['truth'] or '-'}), {row['seconds'] or 0:.1f} s"
            )
        if args.sequential:
            seq_s, seq = run_sequential(manifest, folder)
            print(
                f"one by one (jaxhyst diagnose): {seq_s:.1f} s; 2 workers are "
                f"{seq_s / two_s:.2f}x faster (bar: >= 1.2x)"
            )
            report["sequential_s"] = seq_s
            report["sequential_agrees"] = all(
                seq[n]["findings"] == two[n]["findings"] for n in two
            )
            print(f"findings identical one by one: {report['sequential_agrees']}")
    save()
    if args.json:
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
