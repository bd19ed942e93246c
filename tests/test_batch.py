"""`jaxhyst batch` on a real Dask LocalCluster (two spawned workers of one core):
a worker killed mid-batch, a malformed record among good ones, an interrupted batch
rerun, a manifest error, the summary rebuilt after a record folder is deleted; and
the lock, the done stamps and the summary's reading of a diagnosis, without a
cluster.

The records are tiny fits (a 4-particle, 2-iteration swarm on 300 samples); the
batches share one compilation cache, as a batch's workers do."""

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from jaxhyst._batch import read_manifest, write_summary
from jaxhyst._batch._store import LOCK, BatchLock, BatchLockedError
from jaxhyst._cli import main


pytest.importorskip("distributed")

ROOT = Path(__file__).resolve().parent.parent
TINY = "particles,iterations"


def _recording(path: Path) -> Path:
    t = np.arange(300) * 0.03
    u = 2 - 2 * np.cos(0.2 * np.pi * t)
    y = 0.3 * u + 0.2 * np.tanh(np.gradient(u, t) * 3) + 1e-3 * np.sin(7 * t)
    with open(path, "w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["t", "u", "y"])
        writer.writerows(zip(t, u, y))
    return path


def _manifest(folder: Path, rows: list[str], header: str) -> Path:
    path = folder / "manifest.csv"
    path.write_text("\n".join([header, *rows]) + "\n")
    return path


@pytest.fixture(scope="module")
def cache(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("cache")


def _start(manifest: Path, out: Path, cache: Path, *extra: str) -> subprocess.Popen:
    """`jaxhyst batch` in a child process that answers Ctrl-C (SIGINT), whatever
    this process's disposition: a process that starts with SIGINT ignored keeps it
    ignored (the batch then runs to its end), and the tests run with it ignored
    when a non-interactive shell starts them in the background (`cmd &`)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        return _popen(manifest, out, cache, *extra)
    finally:
        signal.signal(signal.SIGINT, previous)


def _popen(manifest: Path, out: Path, cache: Path, *extra: str) -> subprocess.Popen:
    env = {
        **os.environ,
        "JAXHYST_CACHE_DIR": str(cache),
        "PYTHONPATH": os.pathsep.join(
            [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]
        ),
    }
    return subprocess.Popen(
        [sys.executable, "-m", "jaxhyst", "batch", str(manifest), "--out", str(out)]
        + list(extra),
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _finish(process: subprocess.Popen) -> tuple[int, str, str]:
    stdout, stderr = process.communicate(timeout=240)
    return process.returncode, stdout, stderr


def _summary(out: Path) -> dict[str, dict[str, str]]:
    with open(out / "summary.csv", newline="") as file:
        return {row["name"]: row for row in csv.DictReader(file)}


def _wait_for(condition, timeout: float = 120.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found = condition()
        if found:
            return found
        time.sleep(0.05)
    raise AssertionError("timed out waiting")


def _records(out: Path) -> list[str]:
    return sorted(p.name for p in (out / "records").iterdir())


def _outcome(out: Path, name: str) -> dict:
    return json.loads((out / "records" / name / "outcome.json").read_text())


# ------------------------------------------------------------ without a cluster


@pytest.mark.parametrize(
    ("rows", "header", "words"),
    [
        (["a.csv,fit"], "recording", "no 'command' column"),
        (["a.csv,simulate"], "recording,command", "row 2: command 'simulate'"),
        (["a.csv,fit", "missing.csv,fit"], "recording,command", "row 3: recording"),
        (["a.csv,fit,0"], "recording,command,particles", "row 2: argument"),
        (["a.csv,fit,maybe"], "recording,command,no_time", "row 2: column 'no_time'"),
        (["a.csv,fit,p.json"], "recording,command,json", "row 1: column 'json'"),
        (
            ["a.csv,fit,0.1"],
            "recording,command,min_heldout_gain",
            "row 2: column 'min_heldout_gain' is not an option of 'jaxhyst fit'",
        ),
    ],
)
def test_a_bad_manifest_is_one_line_exit_2_and_nothing_runs(
    tmp_path, capsys, rows, header, words
):
    _recording(tmp_path / "a.csv")
    manifest = _manifest(tmp_path, rows, header)
    out = tmp_path / "out"
    assert main(["batch", str(manifest), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("jaxhyst: error: manifest") and words in err, err
    assert not out.exists()


def test_manifest_options_labels_and_names(tmp_path):
    _recording(tmp_path / "a.csv")
    manifest = read_manifest(
        _manifest(
            tmp_path,
            ["a.csv,fit,4,,1,S1", "a.csv,diagnose,,bouc-wen,yes,S2"],
            "recording,command,particles,model,no_header,specimen",
        )
    )
    first, second = manifest.records
    assert (first.name, second.name) == ("a", "a-2")
    assert first.options == ("--particles", "4", "--no-header")
    assert second.options == ("--model", "bouc-wen", "--no-header")
    assert manifest.label_columns == ("specimen",)
    assert second.labels == (("specimen", "S2"),)


def test_a_repeatable_option_takes_several_values_and_a_switch_off_is_absent(tmp_path):
    _recording(tmp_path / "a.csv")
    manifest = read_manifest(
        _manifest(tmp_path, ["a.csv,fit,u;t,no"], "recording,command,input,no_time")
    )
    assert manifest.records[0].options == ("--input", "u", "--input", "t")


def test_a_live_lock_is_refused_and_a_stale_one_taken_over(tmp_path):
    (tmp_path / LOCK).write_text(f"{os.getpid()} {os.uname().nodename}\n")
    with pytest.raises(BatchLockedError, match="being written by batch pid"):
        BatchLock(tmp_path).acquire()
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    (tmp_path / LOCK).write_text(f"{gone.pid} {os.uname().nodename}\n")
    with BatchLock(tmp_path):
        assert (tmp_path / LOCK).read_text().split()[0] == str(os.getpid())
    assert not (tmp_path / LOCK).exists()


def test_the_summary_reads_a_diagnosis(tmp_path):
    _recording(tmp_path / "a.csv")
    manifest = read_manifest(
        _manifest(tmp_path, ["a.csv,diagnose,S1"], "recording,command,specimen")
    )
    folder = tmp_path / "out" / "records" / "a"
    folder.mkdir(parents=True)
    stamp = {"inputs_sha256": "x", "command": "diagnose", "options": [], "version": "0"}
    (folder / "done").write_text(json.dumps(stamp))
    (folder / "outcome.json").write_text(json.dumps({"seconds": 12.5}))
    (folder / "report.html").write_text("<p>report</p>")
    finding = {
        "effect": "pinching",
        "form": "series_slip",
        "validation": {"heldout_rmse_before": 2.0},
    }
    finding["validation"]["heldout_rmse_after"] = 1.0
    (folder / "result.json").write_text(
        json.dumps(
            {
                "findings": [
                    finding,
                    {
                        **finding,
                        "effect": "degradation",
                        "form": "energy+peak_excursion",
                    },
                ],
                "undecided": ["degradation", "drift"],
                "baseline": {"rmse": 3.0},
                "final": {"rmse": 1.0},
            }
        )
    )
    (row,) = write_summary(tmp_path / "out", manifest)
    assert row.findings == ("pinching", "degradation")
    summary = _summary(tmp_path / "out")["a"]
    assert summary["findings"] == "pinching+degradation"
    assert summary["finding_forms"] == (
        "pinching:series_slip degradation:energy+peak_excursion"
    )
    assert summary["heldout_gains"] == "0.75+0.75"
    assert summary["undecided"] == "degradation+drift"
    assert summary["specimen"] == "S1" and summary["status"] == "done"
    assert (summary["base_rmse"], summary["final_rmse"]) == ("3", "1")
    page = (tmp_path / "out" / "index.html").read_text()
    assert 'href="records/a/report.html"' in page and "pinching" in page


# --------------------------------------------------------------- on a cluster


def test_a_killed_worker_a_malformed_record_and_a_deleted_folder(tmp_path, cache):
    for name in ("a", "b"):
        _recording(tmp_path / f"{name}.csv")
    (tmp_path / "bad.csv").write_text("garbage\n1,2\n")
    manifest = _manifest(
        tmp_path,
        ["a.csv,fit,4,2,S1", "b.csv,fit,4,2,S2", "bad.csv,fit,4,2,S3"],
        f"recording,command,{TINY},specimen",
    )
    out = tmp_path / "out"
    process = _start(manifest, out, cache, "--workers", "2", "--quiet")

    def attempt():
        for each in (out / "records").glob(".tmp-a-*/attempt.json"):
            try:
                return json.loads(each.read_text())["pid"]
            except (OSError, ValueError, KeyError):
                return None
        return None

    killed = _wait_for(attempt)
    os.kill(killed, signal.SIGKILL)
    status, stdout, stderr = _finish(process)
    assert status == 1, stderr
    assert _records(out) == ["a", "b", "bad"], "each record once, no temporary folder"
    summary = _summary(out)
    assert [summary[n]["status"] for n in ("a", "b", "bad")] == [
        "done",
        "done",
        "failed",
    ]
    assert "no column 't'" in summary["bad"]["error"]
    assert (
        summary["bad"]["error"] == (out / "records/bad/error.txt").read_text().strip()
    )
    assert _outcome(out, "a")["pid"] != killed, "a ran again on a new worker"
    assert summary["a"]["specimen"] == "S1" and float(summary["a"]["final_rmse"]) > 0
    for name in ("a", "b"):
        assert {"done", "result.json", "report.html", "log.txt"} <= set(
            os.listdir(out / "records" / name)
        )
    assert not (out / LOCK).exists()

    # A record folder deleted by hand: the summary, rebuilt, says so.
    import shutil

    shutil.rmtree(out / "records" / "b")
    assert main(["batch", str(manifest), "--out", str(out), "--summary-only"]) == 1
    assert _summary(out)["b"]["status"] == "missing"
    assert "missing" in (out / "index.html").read_text()

    # The rerun redoes b (and the failed record), not a.
    before = _outcome(out, "a")
    status, stdout, stderr = _finish(_start(manifest, out, cache, "--workers", "2"))
    assert status == 1, stderr
    assert "1 already done, 2 run" in stdout
    assert _outcome(out, "a") == before
    assert _summary(out)["b"]["status"] == "done"


def test_an_interrupted_batch_resumes(tmp_path, cache):
    names = ("c1", "c2", "c3")
    for name in names:
        _recording(tmp_path / f"{name}.csv")
    manifest = _manifest(
        tmp_path, [f"{n}.csv,fit,4,2" for n in names], f"recording,command,{TINY}"
    )
    out = tmp_path / "out"
    process = _start(manifest, out, cache, "--workers", "1", "--quiet")
    # Dask runs records of one size in no set order: the first one done, whichever.
    _wait_for(lambda: any((out / "records" / n / "done").exists() for n in names))
    process.send_signal(signal.SIGINT)
    status, stdout, stderr = _finish(process)
    assert status == 130, (stdout, stderr)
    assert "interrupted" in stderr
    assert not (out / LOCK).exists()
    finished = [n for n in names if (out / "records" / n / "done").exists()]
    assert 1 <= len(finished) < 3
    assert not any(p.name.startswith(".") for p in (out / "records").iterdir())
    kept = {n: _outcome(out, n) for n in finished}

    status, stdout, stderr = _finish(_start(manifest, out, cache, "--workers", "1"))
    assert status == 0, stderr
    assert f"{len(finished)} already done" in stdout
    assert {n: _outcome(out, n) for n in finished} == kept
    assert [row["status"] for row in _summary(out).values()] == ["done"] * 3


def test_batch_help_and_scheduler_with_workers_refused(tmp_path, capsys):
    assert main(["batch", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "--scheduler ADDRESS" in text and "--retries N" in text
    _recording(tmp_path / "a.csv")
    manifest = _manifest(tmp_path, ["a.csv,fit"], "recording,command")
    argv = ["batch", str(manifest), "--out", str(tmp_path / "out")]
    assert main([*argv, "--scheduler", "tcp://127.0.0.1:1", "--workers", "2"]) == 2
    assert "drop it with --scheduler" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_an_existing_cluster_runs_the_same_records(tmp_path, cache, monkeypatch):
    import distributed

    import jaxhyst as jh

    monkeypatch.setenv("JAXHYST_CACHE_DIR", str(cache))
    _recording(tmp_path / "a.csv")
    manifest = _manifest(tmp_path, ["a.csv,fit,4,2"], f"recording,command,{TINY}")
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, dashboard_address=":0"
    ) as cluster:
        result = jh.batch(
            manifest,
            tmp_path / "out",
            cluster=jh.SchedulerAddress(cluster.scheduler_address),
            progress=False,
        )
    assert (result.ran, result.skipped, result.failed) == (1, 0, 0)
    assert [row.status for row in result.rows] == ["done"]
    assert (tmp_path / "out" / "records" / "a" / "done").exists()


def test_a_worker_keeps_its_programs_until_they_hold_too_many_memory_maps(monkeypatch):
    import jax

    from jaxhyst._batch import _task

    traces = []

    @jax.jit
    def double(x):
        traces.append(1)
        return 2 * x

    double(1.0)
    _task.release_programs_if_many()
    double(1.0)
    assert len(traces) == 1  # kept: the next record of this shape reuses it
    monkeypatch.setattr(_task, "MEMORY_MAPS_LIMIT", 0)
    _task.release_programs_if_many()
    double(1.0)
    assert len(traces) == 2  # released: compiled again


def test_workers_of_a_batch_of_fits_compile_as_the_command_line_does():
    from jaxhyst._batch._run import worker_environment
    from jaxhyst._cli._main import quick_compile_flags

    quick = quick_compile_flags(["fit"], {})
    fits = worker_environment(1, {"fit"}, {})
    mixed = worker_environment(1, {"fit", "diagnose"}, {})
    assert "--xla_cpu_multi_thread_eigen=false" in mixed["XLA_FLAGS"]
    assert fits["OMP_NUM_THREADS"] == "1"
    if quick is not None:  # a jaxlib known to have the flag
        assert quick in fits["XLA_FLAGS"] and quick not in mixed["XLA_FLAGS"]
    mine = worker_environment(2, {"fit"}, {"XLA_FLAGS": "--xla_mine=1"})
    assert mine["XLA_FLAGS"].startswith("--xla_mine=1")
    assert "eigen" not in mine["XLA_FLAGS"]


def test_the_longest_recordings_are_sent_first(tmp_path):
    from jaxhyst._batch._run import RecordTask, submission_order
    from jaxhyst._batch._store import DoneStamp

    sizes = {"a": 10, "b": 300, "c": 20, "d": 300}
    tasks = []
    for name, size in sizes.items():
        (tmp_path / f"{name}.csv").write_text("x" * size)
        tasks.append(
            RecordTask(
                name=name,
                argv=("fit", str(tmp_path / f"{name}.csv")),
                out=str(tmp_path),
                stamp=DoneStamp(
                    inputs_sha256="x", command="fit", options=(), version="0"
                ),
            )
        )
    assert [t.name for t in submission_order(tasks)] == ["b", "d", "c", "a"]
