"""`jaxhyst batch`: diagnose or fit the records of a manifest on a Dask cluster;
resumes, retries records whose worker died, writes one summary."""

import argparse
import sys

from .._batch import (
    BatchInterrupted,
    LocalWorkers,
    SchedulerAddress,
    batch,
    read_manifest,
    write_summary,
)
from .._batch._summary import INDEX, SUMMARY
from ._options import PROG, positive_int


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "batch",
        help="diagnose or fit many recordings listed in a manifest CSV, on a local "
        "or existing Dask cluster; resumes; one summary table and page",
        description=(
            "Run every record of MANIFEST (a CSV: a 'recording' column, a path "
            "absolute or relative to the manifest's folder; a 'command' column, "
            "diagnose or fit; a column named after a long option of that command "
            "without its dashes, e.g. model, no_time, seed, input, start, end, "
            "particles, sets it for the row; an optional 'name' column names the "
            "record's folder; every other column is a label kept in the summary). "
            "Each record is the command run by hand, into OUT/records/NAME/ (its "
            "JSON, report, figures, log and a 'done' file). Running the same batch "
            "again skips the records already done, so an interrupted batch "
            "resumes. A record's error (a malformed file) fails that record only; a "
            "worker that dies is replaced and its record run again. OUT/summary.csv "
            "and OUT/index.html list every record. Exit status: 0 when every record "
            "is done, 1 when some failed, 2 on a usage or manifest error, 130 when "
            "interrupted. Needs dask and distributed (pip install 'jaxhyst[batch]')."
        ),
    )
    parser.add_argument("manifest", metavar="MANIFEST", help="the manifest CSV.")
    parser.add_argument(
        "--out",
        metavar="DIR",
        required=True,
        help="the batch folder (created if missing; rerun with the same DIR to "
        "resume).",
    )
    parser.add_argument(
        "--workers",
        type=positive_int,
        default=None,
        metavar="N",
        help="worker processes of the local cluster (default: the cores divided by "
        "--threads-per-worker).",
    )
    parser.add_argument(
        "--threads-per-worker",
        type=positive_int,
        default=1,
        metavar="T",
        help="cores per worker of the local cluster, XLA's threads included "
        "(default: 1).",
    )
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        default=None,
        help="run on an existing Dask cluster (e.g. tcp://host:8786) instead of a "
        "local one; its workers need jaxhyst, and the recordings and DIR at the same "
        "paths.",
    )
    parser.add_argument(
        "--retries",
        type=int,
        default=2,
        metavar="N",
        help="how many times a record whose worker died is run again (default: 2).",
    )
    parser.add_argument(
        "--summary-only",
        action="store_true",
        help="run nothing: rebuild DIR/summary.csv and DIR/index.html from the "
        "record folders.",
    )
    parser.add_argument(
        "--quiet",
        action="store_true",
        help="no progress line.",
    )
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    if args.retries < 0:
        raise ValueError(f"--retries {args.retries}: pass 0 or more.")
    if args.scheduler is not None and args.workers is not None:
        raise ValueError(
            "--workers is for the local cluster; drop it with --scheduler (the "
            "existing cluster has its own workers)."
        )
    manifest = read_manifest(args.manifest)
    if args.summary_only:
        from pathlib import Path

        out = Path(args.out)
        if not out.is_dir():
            raise FileNotFoundError(
                f"--out {args.out!r} does not exist; run the batch first."
            )
        rows = write_summary(out, manifest)
        print(f"wrote {out / SUMMARY}")
        print(f"wrote {out / INDEX}")
        return 0 if all(row.status == "done" for row in rows) else 1
    cluster = (
        SchedulerAddress(args.scheduler)
        if args.scheduler is not None
        else LocalWorkers(args.workers, args.threads_per_worker)
    )
    try:
        result = batch(
            manifest,
            args.out,
            cluster=cluster,
            retries=args.retries,
            progress=not args.quiet,
        )
    except BatchInterrupted as stop:
        done = sum(row.status == "done" for row in stop.result.rows)
        print(
            f"{PROG}: batch interrupted: {done} of {len(stop.result.rows)} records "
            "done and kept; run the same command again to finish the rest",
            file=sys.stderr,
        )
        print(f"wrote {stop.result.summary}")
        print(f"wrote {stop.result.index}")
        return 130
    done = sum(row.status == "done" for row in result.rows)
    print(
        f"{done} of {len(result.rows)} records done ({result.skipped} already done, "
        f"{result.ran} run), {result.failed} failed"
    )
    for row in result.rows:
        if row.status != "done":
            print(f"  {row.record.name}: {row.status}: {row.error}")
    print(f"wrote {result.summary}")
    print(f"wrote {result.index}")
    return 0 if result.failed == 0 else 1
