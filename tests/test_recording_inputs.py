"""Recordings with several inputs (an MR damper's displacement and command): kept
through every cut and resample, saved and loaded, passed to the simulation as
input channels, and selected with --input repeated on the command line."""

import numpy as np
import pytest

import jaxhyst as jh
from jaxhyst._identification._problem import decimated, stack_inputs


def _damper_like(n=200, name="damper"):
    t = np.arange(n) / 100.0
    x = np.sin(2 * np.pi * 0.7 * t)
    v = 1.0 + 0.5 * np.sign(np.sin(2 * np.pi * 0.2 * t))
    force = 3 * x + v
    return jh.Recording(
        t,
        x,
        force,
        name=name,
        input_name="x",
        output_name="F",
        input_unit="cm",
        output_unit="N",
        more_inputs={"v": v},
        more_input_units={"v": "V"},
    )


def test_more_inputs_follow_every_cut():
    r = _damper_like()
    assert r.input_names == ("x", "v") and r.num_inputs == 2
    v = r.more_input("v")
    part = r.segment(0.5, 1.0)
    np.testing.assert_array_equal(part.more_input("v"), v[50:101])
    first, second = r.split(0.25)
    np.testing.assert_array_equal(second.more_input("v"), v[50:])
    coarse = r.resample(0.02)
    np.testing.assert_allclose(coarse.more_input("v"), v[::2])
    joined = jh.Recording.join([r, r])
    np.testing.assert_array_equal(joined.more_input("v"), np.concatenate([v, v]))
    assert joined.more_input_units == ("V",)
    with pytest.raises(KeyError, match="no further input 'w'"):
        r.more_input("w")


def test_input_path_carries_the_channels():
    r = _damper_like()
    path = r.input_path()
    assert path.num_inputs == 2 and path.channels is not None
    values, rates = path.channels_on_interval(10, 0.5)
    v = r.more_input("v")
    assert float(values[0]) == pytest.approx((v[10] + v[11]) / 2)
    assert float(rates[0]) == pytest.approx((v[11] - v[10]) * 100)
    # Stacking pads every channel like the input; decimation thins them alike.
    short = r.segment(None, 0.5).input_path()
    stacked = stack_inputs([path, short])
    assert stacked.channels is not None and stacked.channels.shape == (2, 1, 200)
    assert float(stacked.channels[1, 0, -1]) == pytest.approx(v[50])
    problem = jh.identification.Problem(
        jh.ParameterSpace.default(jh.PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5), r),
        path,
        r.y,
        jh.RK4(),
    )
    thinned = decimated(problem, 4)
    assert thinned.inputs.channels is not None
    np.testing.assert_array_equal(thinned.inputs.channels[0], v[::4])


@pytest.mark.parametrize("suffix", [".csv", ".npz", ".mat"])
def test_several_inputs_survive_save_and_load(tmp_path, suffix):
    r = _damper_like()
    path = tmp_path / f"damper{suffix}"
    r.save(path)
    back = jh.Recording.load(path, output="F")
    assert back.input_names == ("x", "v")
    assert (back.input_unit, back.more_input_units, back.output_unit) == (
        "cm",
        ("V",),
        "N",
    )
    np.testing.assert_array_equal(back.more_inputs, r.more_inputs)
    # With no columns named, the file reads back whole: its inputs and its output.
    plain = jh.Recording.load(path)
    assert plain.input_names == ("x", "v") and plain.output_name == "F"
    np.testing.assert_array_equal(plain.y, r.y)
    # One input picked explicitly reads only that one.
    assert jh.Recording.load(path, input="x", output="F").input_names == ("x",)


def test_single_input_files_are_written_as_before(tmp_path):
    r = jh.Recording(np.arange(5.0), np.arange(5.0) ** 2, np.arange(5.0))
    r.save(tmp_path / "plain.csv")
    assert (tmp_path / "plain.csv").read_text().splitlines()[0] == "t [s],u,y"


def test_bad_more_inputs_get_clear_errors():
    t = np.arange(10.0)
    with pytest.raises(jh.RecordingError, match="length mismatch.*'v' has 9"):
        jh.Recording(t, t, t, more_inputs={"v": t[:-1]})
    with pytest.raises(jh.RecordingError, match="share a name"):
        jh.Recording(t, t, t, more_inputs={"u": t})
    with pytest.raises(jh.RecordingError, match="NaN/inf"):
        jh.Recording(t, t, t, more_inputs={"v": np.where(t > 3, np.nan, t)})
    with pytest.raises(jh.RecordingError, match="more_input_units names"):
        jh.Recording(t, t, t, more_inputs={"v": t}, more_input_units={"w": "V"})
    one = jh.Recording(t, t, t)
    with pytest.raises(jh.RecordingError, match="same further inputs"):
        jh.Recording.join([one, jh.Recording(t, t, t, more_inputs={"v": t})])


def test_command_line_reads_several_inputs(tmp_path, capsys):
    from jaxhyst._cli import main

    r = _damper_like()
    data = np.stack([r.t, r.u, r.more_input("v"), r.y], axis=1)
    path = tmp_path / "damper.csv"
    np.savetxt(path, data, delimiter=",", header="t,x,v,F", comments="")
    out = tmp_path / "sim.json"
    # A single-input model fits the first input; the command is carried along.
    code = main(
        [
            "fit",
            str(path),
            "--input",
            "x",
            "--input",
            "v",
            "--output",
            "F",
            "--particles",
            "8",
            "--iterations",
            "3",
            "--json",
            str(out),
        ]
    )
    assert code == 0
    text = path.with_suffix(".txt")
    np.savetxt(text, data[:, [1, 3]])
    code = main(["fit", str(text), "--no-time", "--input", "0", "--input", "1"])
    assert code == 2
    assert "--input given 2 times with --no-time" in capsys.readouterr().err


def _spencer_file(tmp_path):
    """A damper test's columns (t, x, v, F); the force is any curve: nothing is
    fitted to it."""
    t = np.arange(601) / 3004.8
    x = 0.5 * np.sin(2 * np.pi * 5 * t)
    v = np.where(t > 0.1, 1.5, 0.0)
    file = tmp_path / "spencer.csv"
    np.savetxt(
        file,
        np.stack([t, x, v, x + v], 1),
        delimiter=",",
        header="t,x,v,F",
        comments="",
    )
    return file


def test_command_line_asks_a_two_input_model_for_its_command(tmp_path, capsys):
    # The fit itself (two inputs, a model file that records them):
    # test_cli_model_inputs.py. Without the command the model cannot run: a
    # one-line error naming the fix, before anything is fitted.
    from jaxhyst._cli import main

    file = _spencer_file(tmp_path)
    out = tmp_path / "fit.json"
    swarm = ["--particles", "8", "--iterations", "2", "--seed", "1"]
    common = ["fit", str(file), "--output", "F", "--model", "spencer", *swarm]
    assert main([*common, "--input", "x", "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert "reads 2 inputs" in err and "--input u --input v" in err
    assert not out.exists()


def test_with_input_adds_a_constant_or_a_column():
    r = _damper_like()
    held = r.with_input("temperature", 21.5, unit="C")
    assert held.input_names == ("x", "v", "temperature")
    assert held.more_input_units == ("V", "C")
    np.testing.assert_array_equal(held.more_input("temperature"), 21.5)
    np.testing.assert_array_equal(held.more_input("v"), r.more_input("v"))
    column = np.linspace(0, 1, r.num_samples)
    np.testing.assert_array_equal(r.with_input("w", column).more_input("w"), column)
    # The original is unchanged.
    assert r.input_names == ("x", "v")
    with pytest.raises(jh.RecordingError, match="already has a column named 'v'"):
        r.with_input("v", 1.0)
    with pytest.raises(jh.RecordingError, match="length mismatch"):
        r.with_input("w", column[:-1])


def test_command_line_reads_a_saved_file_of_several_inputs_whole(tmp_path):
    # No --input, no --output: the inputs and the output the file names.
    from jaxhyst._cli._main import build_parser
    from jaxhyst._cli._options import load_recordings

    r = _damper_like()
    path = tmp_path / "saved.csv"
    r.save(path)
    args = build_parser().parse_args(["diagnose", str(path), "--model", "mr-damper"])
    (back,) = load_recordings(args)
    assert back.input_names == ("x", "v") and back.output_name == "F"
    np.testing.assert_array_equal(back.y, r.y)
