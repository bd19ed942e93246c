"""One record, run on a worker: the command line's own `main` with the row's
options, its outputs into a temporary folder renamed into place.

A task carries paths and options only (a `RecordTask`), never arrays or compiled
functions, so it pickles to any Dask worker that has jaxhyst installed. Running the
record through `jaxhyst._cli.main` makes it what the same command gives by hand:
the same checks, the same one-line user errors (exit status 2), the same files, and
the same persistent compilation cache (which `main` turns on), shared by every
worker of the machine.
"""

import contextlib
import dataclasses
import html
import importlib.util
import json
import os
import socket
import time
import traceback
from pathlib import Path

import jax

from ._store import (
    DONE,
    ERROR,
    DoneStamp,
    commit,
    record_folder,
    temporary_folder,
)


RESULT = "result.json"
OUTCOME = "outcome.json"
LOG = "log.txt"
ATTEMPT = "attempt.json"


@dataclasses.dataclass(frozen=True)
class RecordTask:
    """What a worker needs to run one record: its name, command line (without
    outputs), the batch's folder and the `done` stamp to write when it succeeds."""

    name: str
    argv: tuple[str, ...]
    out: str
    stamp: DoneStamp


@dataclasses.dataclass(frozen=True)
class RecordOutcome:
    """What became of one attempt: `status` is `done` or `failed`; `error` the
    one-line reason of a failure; `seconds` the record's wall time; `pid` and `host`
    the worker process that ran it."""

    name: str
    status: str
    error: str
    seconds: float
    pid: int
    host: str
    cores: int


def _has_matplotlib() -> bool:
    return importlib.util.find_spec("matplotlib") is not None


def _outputs(command: str, folder: Path) -> list[str]:
    out = ["--json", str(folder / RESULT)]
    if _has_matplotlib():
        if command == "diagnose":
            out += ["--report", str(folder / "report.md")]
        else:
            out += ["--plots", str(folder / "figures")]
    return out


def _error_line(log: str) -> str:
    """The command's one-line error from its output (the last `jaxhyst: error:`)."""
    lines = [line for line in log.splitlines() if line.startswith("jaxhyst: error: ")]
    return lines[-1][len("jaxhyst: error: ") :] if lines else ""


def _fit_report(folder: Path, name: str, argv: tuple[str, ...]) -> None:
    """A small HTML page for a fit record (the fit command writes no report): the
    command line, the error measures, the parameters, the figures."""
    data = json.loads((folder / RESULT).read_text(encoding="utf-8"))
    rows = "".join(
        f"<tr><td>{html.escape(str(k))}</td><td>{v:.6g}</td></tr>"
        for k, v in data.get("metrics", {}).items()
        if isinstance(v, (int, float))
    )
    params = "".join(
        f"<tr><td>{html.escape(str(k))}</td><td>{v:.6g}</td></tr>"
        for k, v in data.get("parameters", {}).items()
        if isinstance(v, (int, float))
    )
    figures = folder / "figures"
    images = (
        "".join(
            f'<p><img src="figures/{p.name}" style="max-width:100%"></p>'
            for p in sorted(figures.glob("*.png"))
        )
        if figures.is_dir()
        else ""
    )
    command = html.escape(" ".join(("jaxhyst", *argv)))
    (folder / "report.html").write_text(
        f"<!doctype html><meta charset='utf-8'><title>{html.escape(name)}</title>"
        f"<h1>{html.escape(name)}: fit</h1><p><code>{command}</code></p>"
        f"<h2>Error measures</h2><table>{rows}</table>"
        f"<h2>Parameters</h2><table>{params}</table>{images}"
        f'<p><a href="{RESULT}">{RESULT}</a></p>',
        encoding="utf-8",
    )


MEMORY_MAPS_LIMIT = 30_000
"""Memory maps a worker may hold before it releases its compiled programs: half
the kernel's default `vm.max_map_count` (65530); each compiled CPU program holds
about 80."""


def _memory_maps() -> int | None:
    """How many memory maps this process holds, where the system says (Linux)."""
    try:
        with open("/proc/self/maps", "rb") as maps:
            return sum(1 for _ in maps)
    except OSError:
        return None


def release_programs_if_many() -> None:
    """A worker runs record after record, and records of one shape run the same
    programs: keep them compiled, unless they hold so many memory maps that the
    next compilation could pass the kernel's limit (XLA then crashes); then release
    them all (later records load theirs from the persistent cache). Where the count
    is unknown, release after every record."""
    count = _memory_maps()
    if count is None or count > MEMORY_MAPS_LIMIT:
        jax.clear_caches()


def run_record(task: RecordTask) -> RecordOutcome:
    """Run one record and put its folder in place; returns its outcome. A user
    error (exit status 2) is a failed outcome with the command's one-line message in
    `error.txt`; a crash inside jaxhyst is a failed outcome with the traceback in
    `log.txt`. Only the death of the process loses the attempt (the batch retries
    it)."""
    from .._cli._main import main, store_programs

    store_programs()

    started = time.perf_counter()
    out = Path(task.out)
    folder = temporary_folder(out, task.name)
    pid, host = os.getpid(), socket.gethostname()
    (folder / ATTEMPT).write_text(json.dumps({"pid": pid, "host": host}))
    argv = [*task.argv, *_outputs(task.stamp.command, folder)]
    log_path = folder / LOG
    status: int | None
    with open(log_path, "w", encoding="utf-8") as log:
        with contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
            try:
                status = main(argv)
            except Exception:
                traceback.print_exc()
                status = None
            finally:
                release_programs_if_many()
    log_text = log_path.read_text(encoding="utf-8", errors="replace")
    if status == 0:
        error = ""
        if task.stamp.command == "fit":
            _fit_report(folder, task.name, task.argv)
    elif status is None:
        last = log_text.strip().splitlines()[-1:] or ["(no output)"]
        error = f"internal error: {last[0]} (traceback in log.txt)"
    else:
        error = _error_line(log_text) or f"exit status {status} (see log.txt)"
    seconds = time.perf_counter() - started
    outcome = RecordOutcome(
        name=task.name,
        status="done" if status == 0 else "failed",
        error=error,
        seconds=seconds,
        pid=pid,
        host=host,
        cores=len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 0,
    )
    (folder / OUTCOME).write_text(json.dumps(dataclasses.asdict(outcome), indent=1))
    (folder / ATTEMPT).unlink()
    if status == 0:
        (folder / DONE).write_text(task.stamp.to_json(), encoding="utf-8")
    else:
        (folder / ERROR).write_text(error + "\n", encoding="utf-8")
    commit(folder, record_folder(out, task.name))
    return outcome
