"""`batch`: run a manifest's records on a Dask cluster, skipping the ones already
done, retrying the ones whose worker died, and rebuilding the summary.

The cluster is an option object: `LocalWorkers` (the default: a
`distributed.LocalCluster` started here, worker processes spawned with a fixed share
of the cores each) or `SchedulerAddress` (an existing cluster, e.g. one started by
dask-jobqueue on Slurm). Dask is imported only when a batch runs.
"""

import dataclasses
import importlib.util
import logging
import os
import sys
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from .._threads import host_cores
from ._manifest import Manifest, Record, read_manifest
from ._store import (
    ERROR,
    BatchLock,
    DoneStamp,
    commit,
    file_sha256,
    read_done,
    record_folder,
    remove_temporary,
    temporary_folder,
)
from ._summary import INDEX, SUMMARY, SummaryRow, write_summary
from ._task import RecordOutcome, RecordTask, run_record
from ._worker import THREADS_ENV


@dataclasses.dataclass(frozen=True)
class LocalWorkers:
    """A `distributed.LocalCluster` on this machine: `workers` worker processes
    (default: as many as fit the cores), each running one record at a time on
    `threads_per_worker` cores (XLA's threads and the diagnosis's parallel refits
    included). Workers are spawned processes, never forked."""

    workers: int | None = None
    threads_per_worker: int = 1

    def __post_init__(self):
        if self.workers is not None and self.workers < 1:
            raise ValueError(f"LocalWorkers: workers={self.workers}; pass 1 or more.")
        if self.threads_per_worker < 1:
            raise ValueError(
                f"LocalWorkers: threads_per_worker={self.threads_per_worker}; pass 1 "
                "or more."
            )

    @property
    def count(self) -> int:
        if self.workers is not None:
            return self.workers
        return max(1, host_cores() // self.threads_per_worker)


@dataclasses.dataclass(frozen=True)
class SchedulerAddress:
    """An existing Dask cluster, by its scheduler's address (`tcp://host:8786`).
    Its workers need jaxhyst installed and the recordings and `out` on a shared
    file system, at the same paths."""

    address: str


@dataclasses.dataclass(frozen=True)
class BatchResult:
    """What a batch did: the summary's rows (one per manifest row), how many records
    ran, were skipped (already done) and failed, whether it was interrupted, and
    where the summary is."""

    rows: tuple[SummaryRow, ...]
    ran: int
    skipped: int
    failed: int
    interrupted: bool
    summary: Path
    index: Path


class BatchInterrupted(KeyboardInterrupt):
    """Ctrl-C during a batch: the records that finished are kept; rerunning the
    same batch finishes the rest. `result` is the batch so far."""

    def __init__(self, result: BatchResult):
        super().__init__("batch interrupted")
        self.result = result


def _stamp(record: Record, version: str) -> DoneStamp:
    return DoneStamp(
        inputs_sha256=file_sha256(record.path),
        command=record.command,
        options=record.options,
        version=version,
    )


def _version() -> str:
    from .. import __version__

    return __version__


def _fail_without_worker(out: Path, name: str, error: str) -> None:
    """A record whose attempts never finished (its workers died): its folder with
    only `error.txt`, written like any other."""
    folder = temporary_folder(out, name)
    (folder / ERROR).write_text(error + "\n", encoding="utf-8")
    commit(folder, record_folder(out, name))


def _duration(seconds: float) -> str:
    seconds = int(round(seconds))
    if seconds >= 3600:
        return f"{seconds // 3600}h{seconds % 3600 // 60:02d}m"
    if seconds >= 60:
        return f"{seconds // 60}m{seconds % 60:02d}s"
    return f"{seconds}s"


class _Progress:
    """The progress line on stderr: records done, failed, time left."""

    def __init__(self, total: int, skipped: int, show: bool):
        self.total, self.skipped, self.show = total, skipped, show
        self.done = self.failed = 0
        self.started = time.perf_counter()

    def update(self) -> None:
        if not self.show:
            return
        finished = self.done + self.failed
        left = self.total - finished
        elapsed = time.perf_counter() - self.started
        eta = (
            f", about {_duration(elapsed / finished * left)} left"
            if finished and left
            else ""
        )
        skipped = f" ({self.skipped} already done)" if self.skipped else ""
        tty = sys.stderr.isatty()
        print(
            ("\r" if tty else "")
            + f"batch: {finished}/{self.total} records, {self.done} done, "
            f"{self.failed} failed{skipped}{eta}   ",
            end="" if tty else "\n",
            file=sys.stderr,
            flush=True,
        )

    def clear(self) -> None:
        """End the progress line on a terminal, so that a message can follow."""
        if self.show and sys.stderr.isatty():
            print(file=sys.stderr, flush=True)

    def end(self) -> None:
        if self.show and sys.stderr.isatty():
            print(file=sys.stderr, flush=True)


def worker_environment(
    threads: int, commands: set[str], environ: Mapping[str, str]
) -> dict[str, str]:
    """The environment local workers start with: `threads` XLA and OpenMP threads
    each (one thread: XLA's Eigen thread pool off), and, when every record runs the
    same command, the XLA flags the command line chooses for it
    (`quick_compile_flags`: the elemental emitters for a batch of fits). The user's
    `XLA_FLAGS` are kept and win."""
    from .._cli._main import quick_compile_flags

    flags = environ.get("XLA_FLAGS", "")
    if len(commands) == 1:
        flags = quick_compile_flags(list(commands), {"XLA_FLAGS": flags}) or flags
    if threads == 1 and "xla_cpu_multi_thread_eigen" not in flags:
        flags = f"{flags} --xla_cpu_multi_thread_eigen=false".strip()
    env = {THREADS_ENV: str(threads), "OMP_NUM_THREADS": str(threads)}
    if flags:
        env["XLA_FLAGS"] = flags
    return env


def _client(
    cluster: LocalWorkers | SchedulerAddress,
    say: Callable[[str], None],
    commands: set[str],
):
    """A `distributed.Client` on the cluster, and the LocalCluster to close (or
    None). Local workers run with the XLA flags the command line would choose when
    every record runs the same command (`quick_compile_flags`: the elemental
    emitters for a batch of fits) and with one XLA thread each when asked."""
    try:
        import dask.config
        import distributed
    except ImportError:
        raise ImportError(
            "jaxhyst batch needs Dask: pip install 'jaxhyst[batch]' (dask and "
            "distributed)"
        ) from None
    if isinstance(cluster, SchedulerAddress):
        client = distributed.Client(cluster.address)
        return client, None
    env = worker_environment(cluster.threads_per_worker, commands, os.environ)
    # A free port for the scheduler's HTTP server (the dashboard, with bokeh):
    # several batches may run on one machine, and Dask's default port would warn.
    dashboard = ":0"
    options: dict[str, Any] = {
        "dashboard_address": dashboard,
        "env": env,
        "preload": [f"{__package__}._worker"],
        # Dask's own log lines (a task "marked as failed" when its worker died,
        # workers killed at the end of an interrupted batch) would contradict the
        # batch's, which says what it does about them.
        "silence_logs": logging.CRITICAL,
    }
    # A worker that dies fails its task at once; the batch resubmits it itself
    # (`retries`), so that the count is the same on every cluster.
    with dask.config.set(
        {
            "distributed.scheduler.allowed-failures": 0,
            "distributed.worker.multiprocessing-method": "spawn",
        }
    ):
        local = distributed.LocalCluster(
            n_workers=cluster.count,
            threads_per_worker=1,
            processes=True,
            **options,
        )
        client = distributed.Client(local)
    return client, local


def batch(
    manifest: str | os.PathLike | Manifest,
    out: str | os.PathLike,
    *,
    cluster: LocalWorkers | SchedulerAddress = LocalWorkers(),
    retries: int = 2,
    progress: bool = True,
) -> BatchResult:
    """Run every record of `manifest` (a manifest CSV, or a `Manifest` from
    `read_manifest`) into `out`, on `cluster`.

    **Arguments:**

    - `manifest`: the manifest (see `jaxhyst batch --help` for its columns).
    - `out`: the batch folder: `out/records/<name>/` per record, `out/summary.csv`,
      `out/index.html`.
    - `cluster`: `LocalWorkers(workers, threads_per_worker)` (default: a local
      cluster filling the cores, one core per worker) or
      `SchedulerAddress("tcp://...")` for an existing Dask cluster.
    - `retries`: how many times a record whose worker died is run again.
    - `progress`: print the dashboard address and a progress line on stderr.

    Records whose `done` file matches (same recording bytes, command, options and
    jaxhyst version) are skipped. A record's user error (the command's exit status
    2) fails that record only, with its one-line message in its `error.txt` and the
    summary; it is not retried.

    **Returns:** a `BatchResult`. **Raises:** `ManifestError` before anything runs;
    `BatchLockedError` when another batch writes `out`; `BatchInterrupted` on
    Ctrl-C (what finished stays finished).
    """
    if retries < 0:
        raise ValueError(f"retries={retries}; pass 0 or more.")
    if not isinstance(manifest, Manifest):
        manifest = read_manifest(manifest)
    out = Path(out).absolute()
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(
            f"--out {str(out)!r} is a file; pass a folder (created if missing)."
        )
    say = (
        (lambda text: print(text, file=sys.stderr, flush=True))
        if progress
        else (lambda text: None)
    )
    version = _version()
    with BatchLock(out):
        remove_temporary(out)
        todo: list[RecordTask] = []
        for record in manifest.records:
            stamp = _stamp(record, version)
            if read_done(record_folder(out, record.name)) == stamp:
                continue
            todo.append(
                RecordTask(
                    name=record.name,
                    argv=tuple(record.argv()),
                    out=str(out),
                    stamp=stamp,
                )
            )
        skipped = len(manifest.records) - len(todo)
        meter = _Progress(len(todo), skipped, progress)
        interrupted = False
        if todo:
            interrupted = _run(todo, out, cluster, retries, meter, say)
        else:
            say(f"batch: all {skipped} records already done; nothing to run")
        remove_temporary(out)
        rows = write_summary(out, manifest)
    result = BatchResult(
        rows=tuple(rows),
        ran=meter.done + meter.failed,
        skipped=skipped,
        failed=sum(row.status != "done" for row in rows),
        interrupted=interrupted,
        summary=out / SUMMARY,
        index=out / INDEX,
    )
    if interrupted:
        raise BatchInterrupted(result)
    return result


def _recording_bytes(task: RecordTask) -> int:
    """The size of a task's recording file (its argv is `COMMAND PATH ...`)."""
    try:
        return os.path.getsize(task.argv[1])
    except OSError:
        return 0


def submission_order(todo: list[RecordTask]) -> list[RecordTask]:
    """Longest first, by the recording's size (ties in manifest order): the last
    records to finish are then short ones, so no worker idles while another ends a
    long record. Dask runs them in this order (`priority`)."""
    return sorted(todo, key=_recording_bytes, reverse=True)


def _run(
    todo: list[RecordTask],
    out: Path,
    cluster: LocalWorkers | SchedulerAddress,
    retries: int,
    meter: _Progress,
    say: Callable[[str], None],
) -> bool:
    """Run `todo` on the cluster; returns True when interrupted (Ctrl-C)."""
    client = local = None
    futures = {}
    try:
        client, local = _client(cluster, say, {task.stamp.command for task in todo})
        from distributed import KilledWorker, as_completed

        workers = len(client.scheduler_info().get("workers", {}))
        say(f"batch: {len(todo)} records on {workers} Dask workers")
        if importlib.util.find_spec("bokeh") is not None:
            say(f"batch: dashboard {client.dashboard_link}")
        else:
            say("batch: no dashboard (pip install bokeh to watch the cluster)")
        attempts = {task.name: 0 for task in todo}
        for task in submission_order(todo):
            future = client.submit(
                run_record,
                task,
                key=f"jaxhyst-{task.name}-0",
                pure=False,
                priority=_recording_bytes(task),
            )
            futures[future.key] = (future, task)
        pending = as_completed([f for f, _ in futures.values()])
        meter.update()
        for future in pending:
            _, task = futures.pop(future.key)
            error = future.exception()
            if error is None:
                outcome: RecordOutcome = future.result()
                if outcome.status == "done":
                    meter.done += 1
                else:
                    meter.failed += 1
            elif isinstance(error, KilledWorker) and attempts[task.name] < retries:
                attempts[task.name] += 1
                meter.clear()
                say(
                    f"batch: the worker running {task.name} died; running it again "
                    f"(retry {attempts[task.name]} of {retries})"
                )
                again = client.submit(
                    run_record,
                    task,
                    key=f"jaxhyst-{task.name}-{attempts[task.name]}",
                    pure=False,
                )
                futures[again.key] = (again, task)
                pending.add(again)
            else:
                if isinstance(error, KilledWorker):
                    reason = (
                        f"its worker died {attempts[task.name] + 1} times (killed, "
                        "or out of memory); rerun with more memory per worker "
                        "(fewer --workers) or more --retries"
                    )
                else:
                    reason = f"{type(error).__name__}: {error}"
                _fail_without_worker(out, task.name, reason)
                meter.failed += 1
            meter.update()
        meter.end()
        return False
    except KeyboardInterrupt:
        meter.end()
        return True
    finally:
        if client is not None:
            for future, _ in futures.values():
                future.cancel()
            client.close()
        if local is not None:
            local.close()
