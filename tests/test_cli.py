"""The `jaxhyst` command line (run in-process through `main`) and the plot helpers."""

import dataclasses
import io
import json
import math
import re
import subprocess
import sys

import numpy as np
import pytest

import jaxhyst as jh
from jaxhyst._cli import main
from jaxhyst.report import (
    plot_error_trend,
    plot_loop,
    plot_loop_opening,
    plot_time_history,
    save_figure,
)


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _one_error_line(capsys, *, quiet: bool = False) -> str:
    """The one `jaxhyst: error:` line on stderr; `quiet`: and nothing on stdout."""
    captured = capsys.readouterr()
    if quiet:
        assert captured.out == "", captured.out
    err = captured.err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("jaxhyst: error: "), err
    return lines[0]


def _outputs(folder):
    return folder / "simulation.csv", folder / "loop.png"


def test_default_run_writes_the_paper_simulation(tmp_path, capsys):
    out = tmp_path / "new" / "folder"
    assert main(["simulate", "--out", str(out)]) == 0
    csv_path, png_path = _outputs(out)
    stdout = capsys.readouterr().out
    assert str(csv_path) in stdout and str(png_path) in stdout

    recording = jh.Recording.load(csv_path)
    assert recording.num_samples == 10001
    assert recording.dt == pytest.approx(1e-3)
    assert (recording.input_unit, recording.output_unit) == ("V", "m")
    t = recording.t
    np.testing.assert_allclose(recording.u, 2 - 2 * np.cos(0.2 * np.pi * t), atol=1e-12)
    expected = jh.simulate(
        jh.PiezoBoucWen.paper_table4(3), jh.sample(jh.paper_u1(), 1000.0)
    )
    np.testing.assert_allclose(recording.y, expected, rtol=1e-12, atol=1e-18)
    assert 100e-6 < recording.y.max() < 130e-6  # metres: the loop spans ~117 um
    assert png_path.read_bytes().startswith(PNG_SIGNATURE)


def test_param_override_changes_the_output(tmp_path, capsys):
    assert main(["simulate", "--out", str(tmp_path / "a")]) == 0
    argv = ["simulate", "--param", "k2=0.5", "--param", "n=2", "--out"]
    assert main([*argv, str(tmp_path / "b")]) == 0
    assert "overridden: k2, n" in capsys.readouterr().out
    base = jh.Recording.load(tmp_path / "a" / "simulation.csv")
    changed = jh.Recording.load(tmp_path / "b" / "simulation.csv")
    assert not np.allclose(base.y, changed.y, rtol=1e-6, atol=0)
    model = jh.PiezoBoucWen.paper_table4(3).replace(k2=0.5, n=2.0)
    expected = jh.simulate(model, jh.sample(jh.paper_u1(), 1000.0))
    np.testing.assert_allclose(changed.y, expected, rtol=1e-12, atol=1e-18)


def test_refuses_to_overwrite_without_force(tmp_path, capsys):
    argv = ["simulate", "--rate", "100", "--out", str(tmp_path)]
    assert main(argv) == 0
    csv_path, png_path = _outputs(tmp_path)
    csv_path.write_text("user data\n")
    capsys.readouterr()

    assert main(argv) == 2
    line = _one_error_line(capsys)
    assert "already exist" in line and "--force" in line
    assert csv_path.read_text() == "user data\n"

    assert main([*argv, "--force"]) == 0
    assert jh.Recording.load(csv_path).num_samples == 1001


def test_refuses_when_only_one_output_exists(tmp_path, capsys):
    (tmp_path / "loop.png").write_bytes(b"mine")
    assert main(["simulate", "--rate", "100", "--out", str(tmp_path)]) == 2
    assert "loop.png" in _one_error_line(capsys)
    assert (tmp_path / "loop.png").read_bytes() == b"mine"
    assert not (tmp_path / "simulation.csv").exists()


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["simulate", "--model", "preisach"], "invalid choice: 'preisach'"),
        (["simulate", "--signal", "noise"], "invalid choice: 'noise'"),
        (["simulate", "--periods", "0"], "--periods"),
        (["simulate", "--rate", "fast"], "--rate"),
        (["simulate", "--bogus"], "unrecognized arguments: --bogus"),
        ([], "required: COMMAND"),
        (["fit-everything"], "invalid choice"),
    ],
)
def test_usage_errors_are_one_line_with_exit_2(argv, expected, tmp_path, capsys):
    assert main([*argv, "--out", str(tmp_path)] if argv else argv) == 2
    line = _one_error_line(capsys)
    assert expected in line
    assert "--help" in line
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    "param, expected",
    [
        ("k9=1", "unknown parameter 'k9'"),
        ("k1=abc", "'abc' is not a number"),
        ("k1", "expected NAME=VALUE"),
        ("=3", "expected NAME=VALUE"),
        ("k1=nan", "must be finite"),
    ],
)
def test_bad_param_lists_the_valid_names(param, expected, tmp_path, capsys):
    assert main(["simulate", "--param", param, "--out", str(tmp_path)]) == 2
    line = _one_error_line(capsys)
    assert expected in line
    assert "k1, k2, A1, beta1, gamma1, n" in line
    assert not list(tmp_path.iterdir())


def test_param_names_follow_the_model(tmp_path, capsys):
    argv = ["simulate", "--model", "bouc-wen", "--param", "k1=1", "--out"]
    assert main([*argv, str(tmp_path)]) == 2
    assert "k, alpha, D, A, beta, gamma, n" in _one_error_line(capsys)


def test_out_that_is_a_file_is_an_error(tmp_path, capsys):
    target = tmp_path / "results"
    target.write_text("not a folder")
    assert main(["simulate", "--out", str(target)]) == 2
    assert "is a file, not a folder" in _one_error_line(capsys)


@pytest.mark.parametrize(
    "model, signal",
    [
        ("corrected", "multisine"),
        ("bouc-wen", "triangle"),
        ("stage", "chirp"),
        ("piezo", "u2"),
    ],
)
def test_every_model_and_signal_runs(model, signal, tmp_path, capsys):
    argv = ["simulate", "--model", model, "--signal", signal, "--periods", "0.5"]
    assert main([*argv, "--rate", "200", "--out", str(tmp_path)]) == 0
    recording = jh.Recording.load(tmp_path / "simulation.csv")
    assert recording.num_samples == 1001
    assert np.all(np.isfinite(recording.y)) and np.ptp(recording.y) > 0
    assert "warning" not in capsys.readouterr().err


def test_unstable_parameters_warn(tmp_path, capsys):
    argv = ["simulate", "--model", "bouc-wen", "--signal", "triangle", "--rate", "100"]
    params = ["--param", "beta=-1", "--param", "gamma=-0.5"]
    assert main([*argv, *params, "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert err.startswith("jaxhyst: warning: ") and "Table 2" in err


def test_divergence_is_an_error_and_writes_nothing(tmp_path, capsys):
    argv = ["simulate", "--model", "bouc-wen", "--rate", "100", "--out"]
    params = ["--param", "beta=-5", "--param", "gamma=-5", "--param", "n=2"]
    assert main([*argv, str(tmp_path / "out"), *params]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0].startswith("jaxhyst: warning: ")
    assert err[1].startswith("jaxhyst: error: the simulation diverged")
    assert len(err) == 2
    assert not (tmp_path / "out").exists()


def test_missing_matplotlib_gives_the_install_hint(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    assert main(["simulate", "--out", str(tmp_path / "out")]) == 2
    assert "pip install 'jaxhyst[plot]'" in _one_error_line(capsys)
    assert not (tmp_path / "out").exists()


def test_help_and_version_exit_0(capsys):
    assert main(["--help"]) == 0
    assert "simulate" in capsys.readouterr().out
    assert main(["simulate", "--help"]) == 0
    assert "--param NAME=VALUE" in capsys.readouterr().out
    assert main(["--version"]) == 0
    assert jh.__version__ in capsys.readouterr().out


def test_a_library_error_keeps_its_traceback(tmp_path, capsys, monkeypatch):
    # A ValueError raised inside NumPy (here standing for any bug in how jaxhyst
    # uses a library) is not the user's mistake: it is not turned into one line.
    from jaxhyst._cli import _simulate

    def broken(*args, **kwargs):
        return np.reshape(np.ones(3), (2,))

    monkeypatch.setattr(_simulate, "simulate", broken)
    with pytest.raises(ValueError, match="reshape"):
        main(["simulate", "--out", str(tmp_path / "run")])
    assert "jaxhyst: error" not in capsys.readouterr().err
    # jaxhyst's own checks of what the user gave stay one line.
    assert main(["simulate", "--param", "bogus=1", "--out", str(tmp_path / "b")]) == 2
    assert capsys.readouterr().err.startswith("jaxhyst: error: ")


def test_python_dash_m_runs_the_cli(tmp_path):
    # `python -m jaxhyst` is the same command line; a run that writes files is
    # tested in process (test_default_run_writes_the_paper_simulation), and the
    # installed `jaxhyst` script runs in test_program_store and test_batch.
    result = subprocess.run(
        [sys.executable, "-m", "jaxhyst", "--version"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("jaxhyst ")
    out = tmp_path / "run"
    out.mkdir()
    (out / "simulation.csv").write_text("t,u,y\n")
    again = subprocess.run(
        [sys.executable, "-m", "jaxhyst", "simulate", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert again.returncode == 2
    assert "Traceback" not in again.stderr
    assert again.stderr.startswith("jaxhyst: error: ")


# ------------------------------------------------------------------------ plots


def test_plots_draw_and_save_pngs(tmp_path):
    t = np.linspace(0.0, 10.0, 201)
    u = 2 - 2 * np.cos(0.2 * np.pi * t)
    y = u + 0.1 * np.sin(0.2 * np.pi * t)
    curves = {"measured": y, "model": 1.01 * y}
    drawn = {
        "loop": plot_loop(u, curves, xlabel="u [V]", ylabel="y [um]", title="loop"),
        "opening": plot_loop_opening(u, curves, xlabel="u [V]"),
        "plain": plot_loop(u, {"": y}),
        "history": plot_time_history(t, u, curves, scale=1e6),
        "error": plot_error_trend(t, {"model": 0.01 * y}, log=True),
    }
    assert len(drawn["history"]) == 2  # the input above the outputs
    for name, axes in drawn.items():
        path = save_figure(axes, tmp_path / f"{name}.png")
        assert path == tmp_path / f"{name}.png"
        assert path.read_bytes().startswith(PNG_SIGNATURE)


def test_plots_check_their_inputs(tmp_path):
    u = np.arange(5.0)
    with pytest.raises(ValueError, match="'model' has 4 samples"):
        plot_loop(u, {"model": u[:4]}, xlabel="u", ylabel="y")
    with pytest.raises(ValueError, match="non-empty dict"):
        plot_loop(u, {})
    one = plot_error_trend(u, {"e": u})
    with pytest.raises(ValueError, match="pass 2 Axes"):
        plot_time_history(u, u, {"y": u}, axes=[one])
    with pytest.raises(ValueError, match="not a .png path"):
        save_figure(one, tmp_path / "a.pdf")
    with pytest.raises(FileNotFoundError, match="does not exist"):
        save_figure(one, tmp_path / "missing" / "a.png")
    with pytest.raises(TypeError, match="pass a matplotlib Figure"):
        save_figure("not a figure", tmp_path / "a.png")
    (tmp_path / "taken.png").write_bytes(b"mine")
    history = plot_time_history(u, u, {"y": u})
    with pytest.raises(FileExistsError, match="overwrite=True"):
        save_figure(history, tmp_path / "taken.png")
    assert (tmp_path / "taken.png").read_bytes() == b"mine"
    save_figure(history, tmp_path / "taken.png", overwrite=True)
    assert (tmp_path / "taken.png").read_bytes().startswith(PNG_SIGNATURE)


# ------------------------------------------------------------------- fit, diagnose

# Small swarms keep these quick; the recording is 8 s of u1 at 250 Hz (2001 samples).
QUICK = ["--particles", "16", "--iterations", "30"]
FIT_KEYS = {"model", "parameters", "metrics", "identifiability", "timing", "status"}
METRIC_KEYS = {"rmse", "mad", "mrd", "mae", "nrmsd"}


def _strict_json(path):
    def refuse(constant):
        raise AssertionError(f"{path} holds the non-standard JSON constant {constant}")

    return json.loads(path.read_text(), parse_constant=refuse)


@pytest.fixture(scope="module")
def short_recording(tmp_path_factory):
    """A clean synthetic piezo recording (noise 0.1 % of full scale) as CSV."""
    truth = jh.PiezoBoucWen(k1=0.3, k2=1.0, A1=0.5, beta1=0.6, gamma1=0.2, n=1.5)
    path = jh.sample(jh.paper_u1(periods=0.8), 250.0)
    y = np.asarray(jh.simulate(truth, path))
    y = y + 1e-3 * np.max(np.abs(y)) * np.random.default_rng(0).standard_normal(y.size)
    recording = jh.Recording(
        np.asarray(path.times),
        np.asarray(path.values),
        y,
        name="short",
        input_unit="V",
        output_unit="um",
    )
    file = tmp_path_factory.mktemp("recording") / "short.csv"
    recording.save(file)
    return file


@pytest.fixture(scope="module")
def fitted(short_recording, tmp_path_factory):
    """One `jaxhyst fit` run: (exit status, stdout, output folder)."""
    out = tmp_path_factory.mktemp("fit")
    argv = ["fit", str(short_recording), "--json", str(out / "fit.json")]
    argv += ["--plots", str(out / "figures"), *QUICK]
    with pytest.MonkeyPatch.context() as patch:
        stdout = io.StringIO()
        patch.setattr(sys, "stdout", stdout)
        status = main(argv)
    return status, stdout.getvalue(), out


def test_fit_writes_json_figures_and_summary(fitted):
    status, stdout, out = fitted
    assert status == 0
    data = _strict_json(out / "fit.json")
    assert FIT_KEYS <= set(data)
    assert data["model"] == "PiezoBoucWen"
    assert set(data["parameters"]) == {"k1", "k2", "A1", "beta1", "gamma1", "n"}
    assert METRIC_KEYS <= set(data["metrics"])
    assert data["timing"]["total_s"] > 0
    assert data["metrics"]["nrmsd"] < 0.01  # a clean record fits well
    assert "standard_errors" in data["identifiability"]
    stability = jh.bibo_stability(jh.load_model(out / "fit.json").model)
    assert data["stability"] == {"stable": stability.stable, "reason": stability.reason}
    for name in ("fit_loop", "fit_time_history", "fit_error_trend"):
        assert (out / "figures" / f"{name}.png").read_bytes().startswith(PNG_SIGNATURE)
    for word in ("parameters:", "k1", "RMSE", "MAD", "MRD", "MAE", "NRMSD", "timing:"):
        assert word in stdout
    assert f"wrote {out / 'fit.json'}" in stdout
    # Without --start/--end: the whole record, and the JSON says so.
    assert data["recording"]["samples"] == 2001
    assert data["window"] == {"start": None, "end": None, "time_unit": "s"}
    assert "window:" not in stdout


def test_fit_refuses_to_overwrite_without_force(fitted, short_recording, capsys):
    _, _, out = fitted
    before = (out / "fit.json").read_text()
    argv = ["fit", str(short_recording), "--json", str(out / "fit.json"), *QUICK]
    assert main(argv) == 2
    line = _one_error_line(capsys, quiet=True)  # refused before any computation
    assert "fit.json" in line and "already exists" in line and "--force" in line
    assert (out / "fit.json").read_text() == before
    argv = ["fit", str(short_recording), "--plots", str(out / "figures"), *QUICK]
    assert main(argv) == 2
    assert "fit_loop.png" in _one_error_line(capsys)


@pytest.mark.parametrize(
    "content, options, expected",
    [
        ("t,u,z\n0,0,0\n1,1,1\n2,0,2\n", [], "'y'"),
        ("t,u,y\n0,0,0\n1,nan,1\n2,0,2\n", [], "NaN"),
        ("t,u,y\n0,0,0\n1,1,1\n1,0,2\n", [], "not strictly increasing"),
        ("0,0,0\n1,1,1\n2,0,2\n", ["--no-header", "--time", "t"], "--no-header"),
        (None, [], "does not exist"),
    ],
)
@pytest.mark.parametrize("command", ["fit", "diagnose"])
def test_bad_recordings_are_one_line_errors(
    command, content, options, expected, tmp_path, capsys
):
    path = tmp_path / "recording.csv"
    if content is not None:
        path.write_text(content)
    out = tmp_path / "out.json"
    assert main([command, str(path), *options, "--json", str(out), *QUICK]) == 2
    assert expected in _one_error_line(capsys)
    assert not out.exists()


def test_columns_by_index_without_header(tmp_path, short_recording, capsys):
    recording = jh.Recording.load(short_recording)
    path = tmp_path / "bare.txt"
    np.savetxt(path, np.stack([recording.y, recording.t, recording.u], axis=1))
    argv = ["fit", str(path), "--no-header", "--time", "1", "--input", "2"]
    argv += ["--output", "0", *QUICK]
    assert main(argv) == 0
    assert "2001 samples at 250 Hz" in capsys.readouterr().out


def test_fit_corrected_runs_the_two_stages(short_recording, tmp_path, capsys):
    out = tmp_path / "corrected.json"
    argv = ["fit", str(short_recording), "--model", "corrected", "--json", str(out)]
    assert main([*argv, "--particles", "8", "--iterations", "10"]) == 0
    data = _strict_json(out)
    assert data["model"] == "CorrectedPiezoBoucWen"
    assert {"phi", "eps"} <= set(data["parameters"])
    assert [stage["model"] for stage in data["stages"]] == [
        "PiezoBoucWen",
        "CorrectedPiezoBoucWen",
        "CorrectedPiezoBoucWen",
    ]
    assert data["stages"][2]["rmse"] <= data["stages"][0]["rmse"] * 1.0001
    total = sum(stage["total_s"] for stage in data["stages"])
    assert data["timing"]["total_s"] == pytest.approx(total)
    assert "stages:" in capsys.readouterr().out


def test_fit_several_recordings_reports_each(short_recording, tmp_path, capsys):
    # A second test of the same system: the first 60 % of the record, renamed.
    recording = jh.Recording.load(short_recording)
    keep = int(0.6 * recording.num_samples)
    second = tmp_path / "second.csv"
    jh.Recording(
        recording.t[:keep], recording.u[:keep], recording.y[:keep], name="second"
    ).save(second)
    out = tmp_path / "joint.json"
    argv = ["fit", str(short_recording), str(second), "--json", str(out)]
    argv += ["--plots", str(tmp_path / "figures"), *QUICK]
    assert main(argv) == 0
    stdout = capsys.readouterr().out
    data = _strict_json(out)
    assert data["status"] in ("successful", "max_steps_reached")
    assert data["polish"]["status"] == data["status"]
    assert "recording" not in data
    assert [r["samples"] for r in data["recordings"]] == [2001, keep]
    per = data["metrics"]["per_recording"]
    assert [m["recording"] for m in per] == ["short", "second"]
    assert METRIC_KEYS <= set(per[0])
    # The joint RMSE pools the samples of both records.
    pooled = np.sqrt(
        (per[0]["rmse"] ** 2 * 2001 + per[1]["rmse"] ** 2 * keep) / (2001 + keep)
    )
    assert data["metrics"]["rmse"] == pytest.approx(pooled, rel=1e-9)
    assert "metrics per recording:" in stdout and "on second:" in stdout
    for name in ("short", "second"):
        figure = tmp_path / "figures" / name / "fit_loop.png"
        assert figure.read_bytes().startswith(PNG_SIGNATURE)


def test_fit_preset_and_swarm_options(short_recording, capsys):
    assert main(["fit", str(short_recording), "--preset", "case9"]) == 2
    assert "invalid choice: 'case9'" in _one_error_line(capsys)
    assert main(["fit", str(short_recording), "--particles", "1"]) == 2
    assert "--particles" in _one_error_line(capsys)
    assert main(["fit", "--help"]) == 0
    text = capsys.readouterr().out
    assert "case1" in text and "for quick runs" in text


@pytest.fixture(scope="module")
def diagnosed(short_recording, tmp_path_factory):
    """One `jaxhyst diagnose` run with every output: (status, stdout, folder)."""
    out = tmp_path_factory.mktemp("diagnose")
    argv = ["diagnose", str(short_recording), "--json", str(out / "diagnosis.json")]
    argv += ["--plots", str(out / "figures"), "--report", str(out / "report.md")]
    with pytest.MonkeyPatch.context() as patch:
        stdout = io.StringIO()
        patch.setattr(sys, "stdout", stdout)
        status = main([*argv, *QUICK])
    return status, stdout.getvalue(), out


def test_diagnose_clean_recording_writes_the_contract(diagnosed):
    status, stdout, out = diagnosed
    assert status == 0
    data = _strict_json(out / "diagnosis.json")
    assert data["recording"] == "short"
    assert data["samples"] == 2001
    assert data["model"] == "piezo"
    assert data["noise"]["sigma"] > 0
    assert {"rmse", "nrmsd", "mad", "mae"} <= set(data["baseline"])
    assert isinstance(data["findings"], list)
    assert {"model", "rmse", "parameters"} <= set(data["final"])
    assert data["final"]["model"].startswith("piezo")
    assert isinstance(data["ambiguities"], list)
    assert data["findings"] == []  # a clean record: nothing may be flagged
    assert "findings: none" in stdout and "base model: piezo, fitted on" in stdout
    assert "RMSE on all samples" in stdout
    assert f"wrote {out / 'report.md'}" in stdout
    assert f"wrote {out / 'report.html'}" in stdout
    assert data["window"] == {"start": None, "end": None, "time_unit": "s"}
    assert "window:" not in stdout
    assert data["remainder"]["verdict"] in ("noise-like", "structured")
    # The console shows the JSON's sentence in display units (um as µm).
    sentence = data["remainder"]["sentence"].replace(" um", " µm")
    assert "what is left: " + sentence in stdout


def test_diagnose_report_and_figures(diagnosed):
    _, _, out = diagnosed
    text = (out / "report.md").read_text()
    assert "| model | MAD [µm] | MRD [%] | MAE [µm] | NRMSD | RMSE [µm] |" in text
    assert "| base piezo model (diagnosis) |" in text
    assert "## Findings" in text and "## Ambiguities" in text
    assert "## What is left" in text
    html = (out / "report.html").read_text()
    assert html.count('src="data:image/png;base64,') == len(jh.report.DIAGNOSIS_FIGURES)
    for name in (
        "loop_before_after",
        "error_trend_before_after",
        "residual_time",
        "residual_input",
        "residual_rate",
        "residual_spectrum",
    ):
        assert f"](figures/{name}.png)" in text
        assert (out / "figures" / f"{name}.png").read_bytes().startswith(PNG_SIGNATURE)


def test_fit_window_cuts_the_record(short_recording, tmp_path, capsys):
    out = tmp_path / "fit.json"
    argv = ["fit", str(short_recording), "--start", "2", "--end", "6", "--json"]
    assert main([*argv, str(out), "--particles", "8", "--iterations", "3"]) == 0
    data = _strict_json(out)
    assert data["recording"]["samples"] == 1001  # 4 s at 250 Hz
    assert data["window"] == {"start": 2.0, "end": 6.0, "time_unit": "s"}
    stdout = capsys.readouterr().out
    assert "1001 samples at 250 Hz over 4 s" in stdout
    assert "window: t from 2 to 6 s (--start 2, --end 6), 1001 samples" in stdout
    # One side only: from 6 s to the end.
    argv = ["fit", str(short_recording), "--start", "6", "--force", "--json"]
    assert main([*argv, str(out), "--particles", "8", "--iterations", "3"]) == 0
    data = _strict_json(out)
    assert data["recording"]["samples"] == 501
    assert data["window"] == {"start": 6.0, "end": None, "time_unit": "s"}


class _Stop(Exception):
    pass


@pytest.fixture
def stopped_diagnose(monkeypatch):
    """`diagnose` replaced by a stub that records what the CLI passes it (the
    recording and the keyword arguments) and stops with `_Stop`."""
    seen = []

    def stub(recording, **kwargs):
        seen.append((recording, kwargs))
        raise _Stop

    monkeypatch.setattr("jaxhyst._cli._diagnose.diagnose", stub)
    return seen


def test_diagnose_analyses_the_window(short_recording, stopped_diagnose):
    """diagnose gets the cut recording, with its original time stamps (the
    diagnosis itself is replaced by a stub: the window is all that is tested)."""
    seen = stopped_diagnose
    with pytest.raises(_Stop):
        main(["diagnose", str(short_recording), "--start", "1.5", "--end", "7"])
    ((recording, _),) = seen
    assert recording.num_samples == 1376  # 5.5 s at 250 Hz
    assert recording.t[0] == pytest.approx(1.5) and recording.t[-1] == pytest.approx(7)
    full = jh.Recording.load(short_recording)
    np.testing.assert_array_equal(recording.y, full.y[375:1751])
    seen.clear()
    with pytest.raises(_Stop):
        main(["diagnose", str(short_recording)])
    assert seen[0][0].num_samples == 2001


def test_diagnose_passes_the_minimum_held_out_gain(short_recording, stopped_diagnose):
    """--min-heldout-gain replaces the family's default in the policy diagnose
    gets (the rest of the policy kept); without it the family's default is used."""
    seen = stopped_diagnose
    argv = ["diagnose", str(short_recording)]
    with pytest.raises(_Stop):
        main([*argv, "--min-heldout-gain", "0.02"])
    policy = seen[0][1]["policy"]
    default = jh.families.PiezoFamily().default_policy()
    assert policy.min_heldout_gain == 0.02
    assert policy == dataclasses.replace(default, min_heldout_gain=0.02)
    with pytest.raises(_Stop):
        main(argv)
    assert seen[1][1]["policy"] is None


@pytest.mark.parametrize("value", ["1.5", "-0.1"])
def test_a_bad_minimum_held_out_gain_is_a_one_line_error(
    value, short_recording, capsys
):
    argv = ["diagnose", str(short_recording), "--min-heldout-gain", value]
    assert main(argv) == 2
    line = _one_error_line(capsys)
    assert f"--min-heldout-gain {float(value)}" in line and "[0, 1)" in line


@pytest.mark.parametrize(
    "window, expected",
    [
        (["--start", "5", "--end", "3"], "--start 5 --end 3: the window is empty"),
        (["--start", "2", "--end", "2"], "pass --start below --end"),
        (["--start", "9"], "--start 9 is at or past the end of the record"),
        (["--end", "-1"], "--end -1 is at or before the start of the record"),
        (["--start", "1", "--end", "1.001"], "holds 1 sample(s)"),
        (["--start", "nan"], "--start: nan must be finite"),
        (["--end", "soon"], "--end: 'soon' is not a number"),
    ],
)
@pytest.mark.parametrize("command", ["fit", "diagnose"])
def test_bad_windows_are_one_line_errors(
    command, window, expected, short_recording, tmp_path, capsys
):
    out = tmp_path / "out.json"
    argv = [command, str(short_recording), *window, "--json", str(out), *QUICK]
    assert main(argv) == 2
    line = _one_error_line(capsys, quiet=True)
    assert expected in line
    if "past the end" in expected or "before the start" in expected:
        assert f"the record {str(short_recording)!r} runs from t = 0 to 8 s" in line
    assert not out.exists()


def test_window_help_says_samples_for_quasi_static_records(capsys):
    for command in ("fit", "diagnose"):
        assert main([command, "--help"]) == 0
        text = " ".join(capsys.readouterr().out.split())
        assert "--start T" in text and "--end T" in text
        assert "with --no-time, T is a sample index" in text


def test_diagnose_refuses_to_overwrite(diagnosed, short_recording, capsys):
    _, _, out = diagnosed
    before = (out / "report.md").read_text()
    argv = ["diagnose", str(short_recording), "--report", str(out / "report.md")]
    assert main([*argv, "--plots", str(tmp := out / "elsewhere"), *QUICK]) == 2
    assert "report.md" in _one_error_line(capsys)
    assert (out / "report.md").read_text() == before
    assert not tmp.exists()


@pytest.mark.parametrize("model", ["corrected", "bouc", "stage"])
def test_diagnose_names_the_families_it_has(model, short_recording, capsys):
    assert main(["diagnose", str(short_recording), "--model", model]) == 2
    line = _one_error_line(capsys)
    assert f"--model {model}" in line and "--model bouc-wen" in line


def test_diagnose_bouc_wen_needs_a_cyclic_record(tmp_path, capsys):
    path = tmp_path / "ramp.txt"
    np.savetxt(path, np.stack([np.arange(300.0), 2 * np.arange(300.0)], axis=1))
    assert main(["diagnose", str(path), "--no-time", "--model", "bouc-wen"]) == 2
    assert "reversal" in _one_error_line(capsys)


def test_diagnose_too_short_recording(tmp_path, capsys):
    t = np.arange(50) * 0.01
    jh.Recording(t, np.sin(t), np.cos(t)).save(tmp_path / "tiny.csv")
    assert main(["diagnose", str(tmp_path / "tiny.csv"), *QUICK]) == 2
    assert "200" in _one_error_line(capsys)


# ------------------------------------------------------------------------- demo


@pytest.mark.parametrize("name", ["report.md", "report.html"])
def test_demo_refuses_to_overwrite_before_computing(name, tmp_path, capsys):
    (tmp_path / name).write_text("mine")
    assert main(["demo", "--out", str(tmp_path)]) == 2
    line = _one_error_line(capsys, quiet=True)
    assert name in line and "--force" in line
    assert (tmp_path / name).read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]


@pytest.mark.slow
def test_demo_end_to_end(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out)]) == 0
    stdout = capsys.readouterr().out
    assert f"report: {out / 'report.md'}" in stdout
    recording = jh.Recording.load(out / "recording.csv")
    assert recording.num_samples == jh.synthetic.demo_recording().recording.num_samples
    fit = _strict_json(out / "fit.json")
    assert FIT_KEYS <= set(fit)
    diagnosis = _strict_json(out / "diagnosis.json")
    assert diagnosis["findings"], "the demo recording conceals two effects"
    assert diagnosis["final"]["rmse"] < diagnosis["baseline"]["rmse"]
    text = (out / "report.md").read_text()
    assert "| model | MAD [µm] | MRD [%] | MAE [µm] | NRMSD | RMSE [µm] |" in text
    for number in range(8, 14):
        assert f"**Figure {number}.**" in text
    links = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    assert links and all((out / link).is_file() for link in links)
    html = (out / "report.html").read_text()
    assert html.count('src="data:image/png;base64,') == len(links)
    assert main(["demo", "--out", str(out)]) == 2  # no --force: refused


# ------------------------------------------------------------ quasi-static files


@pytest.fixture(scope="module")
def two_columns(tmp_path_factory):
    """A Bouc-Wen force under a growing cyclic displacement, 241 rows of
    "displacement force" without header or time."""
    k = np.arange(241)
    displacement = 0.01 * k * np.sin(2 * np.pi * k / 40)
    model = jh.BoucWen(k=2.0, alpha=0.3, D=1.0, A=1.0, beta=0.5, gamma=0.5, n=1.5)
    force = np.asarray(jh.simulate(model, jh.InputPath(0.0, 1.0, displacement)))
    path = tmp_path_factory.mktemp("quasi_static") / "cyclic.txt"
    np.savetxt(path, np.stack([displacement, force], axis=1))
    return path, displacement, force


class TestNoTime:
    """`--no-time`: a two-column (displacement, force) file read with the pseudo
    time t = sample index."""

    def test_fit_reads_a_two_column_file(self, two_columns, tmp_path, capsys):
        path, displacement, force = two_columns
        out = tmp_path / "fit.json"
        argv = ["fit", str(path), "--no-time", "--model", "bouc-wen"]
        assert main([*argv, "--particles", "8", "--iterations", "3"]) == 0
        assert "241 samples at 1 Hz over 240 s" in capsys.readouterr().out
        # Comma-separated, columns swapped and picked by index, with a JSON.
        swapped = tmp_path / "swapped.csv"
        np.savetxt(swapped, np.stack([force, displacement], axis=1), delimiter=",")
        argv = ["fit", str(swapped), "--no-time", "--input", "1", "--output", "0"]
        argv += ["--model", "bouc-wen", "--particles", "8", "--iterations", "3"]
        assert main([*argv, "--json", str(out)]) == 0
        data = _strict_json(out)
        assert data["recording"]["samples"] == 241
        assert data["model"] == "BoucWen"
        assert math.isfinite(data["metrics"]["rmse"])
        recording = jh.Recording.load(swapped, time=None, input=1, output=0)
        np.testing.assert_allclose(recording.u, displacement, rtol=1e-15)
        np.testing.assert_allclose(recording.y, force, rtol=1e-15)
        np.testing.assert_array_equal(recording.t, np.arange(241.0))

    @pytest.mark.parametrize(
        "content, options, expected",
        [
            ("0 0\n1 2\n2 3\n1\n", [], "two columns of different lengths (4 and 3"),
            ("0,0\n1,2\n2,3\n1,\n", [], "two columns of different lengths (4 and 3"),
            ("0 0 0\n1 2 1\n2 3 2\n", [], "line 1 has 3 columns"),
            ("0 0\n1 2\n2 3\n", ["--time", "0"], "--time 0 with --no-time"),
            ("0 0\n1 2\n2 3\n", ["--input", "2"], "pick 0 or 1"),
        ],
    )
    def test_bad_files_and_options_are_one_line_errors(
        self, content, options, expected, tmp_path, capsys
    ):
        path = tmp_path / "recording.txt"
        path.write_text(content)
        out = tmp_path / "out.json"
        argv = ["fit", str(path), "--no-time", *options, "--json", str(out)]
        assert main([*argv, "--model", "bouc-wen", *QUICK]) == 2
        assert expected in _one_error_line(capsys, quiet=True)
        assert not out.exists()

    def test_window_is_in_samples(self, two_columns, tmp_path, capsys):
        path, _, force = two_columns
        out = tmp_path / "fit.json"
        argv = ["fit", str(path), "--no-time", "--model", "bouc-wen", "--start"]
        argv += ["40", "--end", "120", "--particles", "8", "--iterations", "3"]
        assert main([*argv, "--json", str(out)]) == 0
        data = _strict_json(out)
        assert data["recording"]["samples"] == 81  # samples 40 to 120
        assert data["window"] == {"start": 40.0, "end": 120.0, "time_unit": "sample"}
        stdout = capsys.readouterr().out
        assert "window: samples 40 to 120 (--start 40, --end 120), 81 samples" in stdout

    def test_help_describes_the_option(self, capsys):
        assert main(["fit", "--help"]) == 0
        text = " ".join(capsys.readouterr().out.split())
        assert "--no-time" in text and "pseudo time t = sample index" in text


@pytest.mark.parametrize("seed", [0, 1, 7, 2**31, 2**32 + 5, 2**63 - 1, -1, -(2**63)])
def test_seed_keys_are_jax_random_keys(seed):
    import jax

    from jaxhyst._cli._choices import prng_key

    made = prng_key(seed)
    expected = jax.random.key(seed)
    assert made.dtype == expected.dtype
    np.testing.assert_array_equal(
        jax.random.key_data(made), jax.random.key_data(expected)
    )
    # The same draws, not only the same words.
    np.testing.assert_array_equal(
        jax.random.uniform(made, (3,)), jax.random.uniform(expected, (3,))
    )


def test_seed_keys_without_64_bit_jax_are_jax_random_keys():
    import jax

    from jaxhyst._cli._choices import prng_key

    with jax.enable_x64(False):
        for seed in (3, -1):
            np.testing.assert_array_equal(
                jax.random.key_data(prng_key(seed)),
                jax.random.key_data(jax.random.key(seed)),
            )
