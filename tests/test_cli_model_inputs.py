"""`jaxhyst evaluate` and `compensate` read the columns a model was fitted from:
the model file records them, explicit --input/--output win, a file without them
is one line naming the file, the column and the flag."""

import argparse
import json

import numpy as np
import pytest

import jaxhyst as jh
from jaxhyst._cli._evaluate import columns_by_name
from jaxhyst._cli._main import main
from jaxhyst._model_files import checksum


TINY = ["--particles", "4", "--iterations", "2"]
_DAMPER = jh.SpencerDamper.spencer_1997()
_PIEZO = jh.PiezoBoucWen(k1=0.3, k2=1.0, A1=0.5, beta1=0.6, gamma1=0.2, n=1.5)


def _damper_test(frequency: float, phase: float) -> dict[str, np.ndarray]:
    """A short damper test (N, cm, s): displacement u, command v, force y."""
    t = np.arange(200) / 200.0
    u = np.sin(2 * np.pi * frequency * t)
    v = 1.0 + 0.5 * np.sin(2 * np.pi * 0.7 * t + phase)
    recording = jh.Recording(t, u, np.zeros_like(u), more_inputs={"v": v})
    path = recording.input_path()
    y = np.asarray(jh.simulate(_DAMPER, path, _DAMPER.default_solver(recording)))
    return {"t": t, "u": u, "v": v, "y": y}


def _csv(path, columns: dict[str, np.ndarray]):
    table = np.stack(list(columns.values()), axis=1)
    header = ",".join(columns)
    np.savetxt(path, table, delimiter=",", header=header, comments="", fmt="%.17g")
    return path


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("damper")
    fitted, other = _damper_test(2.0, 0.0), _damper_test(3.0, 1.0)
    w = 2.0 - other["v"]  # another command than v
    return {
        "fitted": _csv(folder / "fitted.csv", fitted),
        "other": _csv(folder / "other.csv", other),
        # The same test under other names, and with a second command column.
        "renamed": _csv(
            folder / "renamed.csv",
            {"t": other["t"], "x": other["u"], "cmd": other["v"], "y": other["y"]},
        ),
        "two_commands": _csv(
            folder / "two_commands.csv",
            {**{k: other[k] for k in "tuv"}, "w": w, "y": other["y"]},
        ),
        "no_v": _csv(folder / "no_v.csv", {k: other[k] for k in "tuy"}),
        "no_y": _csv(
            folder / "no_y.csv", {**{k: other[k] for k in "tuv"}, "F": other["y"]}
        ),
    }


@pytest.fixture(scope="module")
def fit_json(files, tmp_path_factory):
    out = tmp_path_factory.mktemp("fit") / "fit.json"
    argv = ["fit", "--model", "spencer", str(files["fitted"]), "--input", "u"]
    argv += ["--input", "v", "--json", str(out), *TINY]
    assert main(argv) == 0
    return out


def _evaluate(capsys, *argv) -> tuple[int, str]:
    capsys.readouterr()
    status = main(["evaluate", *map(str, argv)])
    captured = capsys.readouterr()
    return status, captured.out + captured.err


def _metrics(capsys, tmp_path, model, recording, *flags) -> dict[str, float]:
    out = tmp_path / f"e{len(list(tmp_path.iterdir()))}.json"
    status, text = _evaluate(capsys, model, recording, *flags, "--json", out)
    assert status == 0, text
    return json.loads(out.read_text())["recordings"][0]["metrics"]


def _one_error_line(text: str) -> str:
    lines = text.strip().splitlines()
    assert len(lines) == 1, text
    assert lines[0].startswith("jaxhyst: error: "), text
    return lines[0]


def test_the_model_file_records_the_columns(fit_json):
    data = json.loads(fit_json.read_text())
    assert data["model"] == "SpencerDamper"
    entry = data["model_file"]["recordings"][0]
    assert entry["inputs"] == ["u", "v"] and entry["output"] == "y"
    loaded = jh.load_model(fit_json)
    assert type(loaded.model) is jh.SpencerDamper
    assert loaded.columns == (("u", "v"), "y")


def test_evaluate_reads_the_fitted_columns(fit_json, files, tmp_path, capsys):
    status, text = _evaluate(capsys, fit_json, files["other"])
    assert status == 0, text
    assert "columns: u, v -> y" in text
    default = _metrics(capsys, tmp_path, fit_json, files["other"])
    given = _metrics(
        capsys, tmp_path, fit_json, files["other"], "--input", "u", "--input", "v"
    )
    assert default == given
    # What the library gives on u and v.
    model = jh.load_model(fit_json).model
    recording = jh.Recording.load(files["other"], input=["u", "v"])
    y = jh.simulate(model, recording.input_path(), model.default_solver(recording))
    assert default == jh.error_metrics(recording.y, y)


def test_explicit_inputs_win(fit_json, files, tmp_path, capsys):
    default = _metrics(capsys, tmp_path, fit_json, files["other"])
    # Another command column: read only when asked for.
    same = _metrics(capsys, tmp_path, fit_json, files["two_commands"])
    assert same == default
    other = _metrics(
        capsys,
        tmp_path,
        fit_json,
        files["two_commands"],
        "--input",
        "u",
        "--input",
        "w",
    )
    assert other != default
    # Other names: --input picks them, the output is still the model's y.
    renamed = _metrics(
        capsys, tmp_path, fit_json, files["renamed"], "--input", "x", "--input", "cmd"
    )
    assert renamed == default


def test_a_file_without_a_column_is_one_line(fit_json, files, capsys):
    status, text = _evaluate(capsys, fit_json, files["no_v"])
    assert status == 2
    line = _one_error_line(text)
    for word in (str(files["no_v"]), "'v'", "command", "t, u, y", "--input NAME"):
        assert word in line, line
    status, text = _evaluate(capsys, fit_json, files["no_y"])
    assert status == 2
    line = _one_error_line(text)
    for word in (str(files["no_y"]), "'y'", "t, u, v, F", "--output NAME"):
        assert word in line, line
    # With --output the output is found.
    assert main(["evaluate", str(fit_json), str(files["no_y"]), "--output", "F"]) == 0
    status, text = _evaluate(capsys, fit_json, files["renamed"])
    assert status == 2
    assert "'u'" in _one_error_line(text)


def _old_format(path):
    """`path` as a model file written before the column names were recorded."""
    data = json.loads(path.read_text())
    for entry in data["recordings"]:
        del entry["inputs"], entry["output"]
    data["checksum"] = checksum(data)
    path.write_text(json.dumps(data))
    return path


@pytest.fixture(scope="module")
def piezo(tmp_path_factory):
    folder = tmp_path_factory.mktemp("piezo")
    path = jh.sample(jh.Triangle(2.0, 0.5, duration=2.0), 100.0)
    t, u = np.asarray(path.times), np.asarray(path.values)
    y = np.asarray(jh.simulate(_PIEZO, path))
    recording = jh.Recording(t, u, y, name="piezo", input_name="V", output_name="x")
    return {
        "model": jh.save_model(_PIEZO, folder / "model.json", recording=recording),
        "old": _old_format(
            jh.save_model(_PIEZO, folder / "old.json", recording=recording)
        ),
        "named": _csv(folder / "named.csv", {"t": t, "V": u, "x": y}),
        "plain": _csv(folder / "plain.csv", {"t": t, "u": u, "y": y}),
        "reference": _csv(folder / "reference.csv", {"t": t, "x": 0.8 * y}),
        "plain_reference": _csv(folder / "plain_reference.csv", {"t": t, "y": 0.8 * y}),
    }


def test_an_old_model_file_reads_u_and_y(piezo, tmp_path, capsys):
    loaded = jh.load_model(piezo["old"])
    assert loaded.columns is None
    assert "inputs" not in loaded.recordings[0]
    old = _metrics(capsys, tmp_path, piezo["old"], piezo["plain"])
    assert old["nrmsd"] < 1e-12
    # The new file reads its own names; --input/--output read the plain file.
    assert jh.load_model(piezo["model"]).columns == (("V",), "x")
    assert _metrics(capsys, tmp_path, piezo["model"], piezo["named"]) == old
    flags = ("--input", "u", "--output", "y")
    assert _metrics(capsys, tmp_path, piezo["model"], piezo["plain"], *flags) == old
    status, text = _evaluate(capsys, piezo["model"], piezo["plain"])
    assert status == 2
    assert "'V'" in _one_error_line(text) and "--input NAME" in text


def _compensate(capsys, model, reference, out, *flags) -> tuple[int, str]:
    capsys.readouterr()
    argv = ["compensate", str(model), str(reference), "--out", str(out), *flags]
    status = main(argv)
    captured = capsys.readouterr()
    return status, captured.out + captured.err


def test_compensate_reads_the_fitted_output(piezo, fit_json, tmp_path, capsys):
    first, second = tmp_path / "a.csv", tmp_path / "b.csv"
    status, text = _compensate(capsys, piezo["model"], piezo["reference"], first)
    assert status == 0, text
    # The old file, and --output, read the plain reference's y: the same drive.
    status, text = _compensate(capsys, piezo["old"], piezo["plain_reference"], second)
    assert status == 0, text
    assert first.read_text() == second.read_text()
    status, text = _compensate(
        capsys,
        piezo["model"],
        piezo["plain_reference"],
        second,
        "--output",
        "y",
        "--force",
    )
    assert status == 0, text
    assert first.read_text() == second.read_text()
    # Without --output the model's output column is looked for, and named.
    status, text = _compensate(
        capsys, piezo["model"], piezo["plain_reference"], tmp_path / "c.csv"
    )
    assert status == 2
    line = _one_error_line(text)
    for word in (str(piezo["plain_reference"]), "'x'", "t, y", "--output NAME"):
        assert word in line, line
    # A model of two inputs has no one drive to find.
    status, text = _compensate(capsys, fit_json, piezo["reference"], tmp_path / "d.csv")
    assert status == 2
    assert "reads 2 inputs" in _one_error_line(text)


@pytest.mark.parametrize(
    "flags, expected",
    [
        ({}, True),
        ({"input": ["u", "v"], "output": "F"}, True),
        ({"no_header": True}, False),
        ({"no_time": True}, False),
        ({"input": ["1"]}, False),
        ({"output": "2"}, False),
    ],
)
def test_only_columns_read_by_name_are_recorded(flags, expected):
    args = argparse.Namespace(
        **{"no_header": False, "no_time": False, "input": None, "output": None, **flags}
    )
    assert columns_by_name(args) is expected
