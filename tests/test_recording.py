import jax
import numpy as np
import pytest
import scipy.io

import jaxhyst as jh
from jaxhyst import Recording, RecordingError


def _arrays(n=101, dt=0.01):
    t = 0.5 + dt * np.arange(n)
    u = np.sin(2 * np.pi * t)
    y = 0.5 * u + 0.1 * np.cos(2 * np.pi * t)
    return t, u, y


def _recording(**kwargs):
    return Recording(*_arrays(), name="rec", **kwargs)


def _assert_same(a, b):
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a.u, b.u)
    np.testing.assert_array_equal(a.y, b.y)
    for field in (
        "name",
        "input_name",
        "output_name",
        "input_unit",
        "output_unit",
        "time_unit",
    ):
        assert getattr(a, field) == getattr(b, field), field


# ------------------------------------------------------------------- construction


def test_basic_properties():
    rec = _recording()
    assert rec.num_samples == 101
    assert rec.dt == pytest.approx(0.01)
    assert rec.sample_rate == pytest.approx(100.0)
    assert rec.duration == pytest.approx(1.0)
    assert rec.t.dtype == np.float64 and rec.u.dtype == np.float64
    assert (rec.name, rec.input_name, rec.output_name) == ("rec", "u", "y")
    assert rec.time_unit == "s" and rec.input_unit == ""
    with pytest.raises(ValueError):
        rec.u[0] = 1.0  # read-only


def test_accepts_integer_and_list_inputs():
    rec = Recording([0, 1, 2], [0, 1, 0], [1, 2, 3])
    assert rec.u.dtype == np.float64


def test_timestamp_jitter_is_accepted():
    t, u, y = _arrays()
    jitter = 1e-8 * np.sin(np.arange(t.size))  # 1e-6 of the step
    rec = Recording(t + jitter, u, y)
    assert rec.dt == pytest.approx(0.01)


def test_length_mismatch():
    t, u, y = _arrays()
    with pytest.raises(RecordingError, match="length mismatch"):
        Recording(t, u[:-1], y)


def test_not_one_dimensional():
    t, u, y = _arrays()
    with pytest.raises(RecordingError, match="one-dimensional"):
        Recording(t, u[:, None], y)


def test_non_numeric():
    t, u, y = _arrays(n=3)
    with pytest.raises(RecordingError, match="not numeric"):
        Recording(t, ["a", "b", "c"], y)


def test_too_few_samples():
    with pytest.raises(RecordingError, match="at least 2"):
        Recording([0.0], [1.0], [1.0])


@pytest.mark.parametrize("column", ["t", "u", "y"])
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_nan_and_inf(column, bad):
    t, u, y = _arrays()
    arrays = {"t": t, "u": u, "y": y}
    arrays[column][7] = bad
    with pytest.raises(RecordingError) as info:
        Recording(arrays["t"], arrays["u"], arrays["y"], output_name="force")
    message = str(info.value)
    assert "NaN/inf" in message and "row 7" in message and "interpolate" in message
    assert {"t": "time", "u": "input", "y": "output 'force'"}[column] in message


def test_non_monotonic_time():
    t, u, y = _arrays()
    t[5] = t[4]
    with pytest.raises(RecordingError, match=r"not strictly increasing at row 5"):
        Recording(t, u, y)


def test_non_uniform_time_and_resample_option():
    t = np.sort(np.r_[0.0, 1.0, np.random.default_rng(0).uniform(0, 1, 50)])
    u = np.sin(3 * t)
    y = u**2
    with pytest.raises(RecordingError) as info:
        Recording(t, u, y)
    assert "not uniformly sampled" in str(info.value)
    assert "resample=True" in str(info.value)
    rec = Recording(t, u, y, resample=True)
    assert rec.num_samples == t.size
    np.testing.assert_allclose(np.diff(rec.t), 1.0 / (t.size - 1), rtol=1e-9)
    assert rec.t[0] == 0.0 and rec.t[-1] == 1.0
    np.testing.assert_allclose(rec.u, np.interp(rec.t, t, u))


def test_constant_input():
    t, _, y = _arrays()
    with pytest.raises(RecordingError, match="nothing excites the hysteresis"):
        Recording(t, np.full(t.size, 2.0), y)


def test_option_types():
    with pytest.raises(TypeError, match="input_unit"):
        Recording(*_arrays(), input_unit=3)


# ------------------------------------------------------------------------ methods


def test_passes_through_jit():
    rec = _recording()
    value = jax.jit(lambda r: jh.metrics.rmse(r.y, 0 * r.y))(rec)
    assert float(value) == pytest.approx(np.sqrt(np.mean(rec.y**2)))


def test_input_path():
    rec = _recording()
    path = rec.input_path()
    assert isinstance(path, jh.InputPath)
    assert float(path.t0) == pytest.approx(0.5)
    assert float(path.dt) == pytest.approx(0.01)
    np.testing.assert_allclose(np.asarray(path.values), rec.u)
    cubic = rec.input_path(interpolation=jh.CubicInterpolation())
    assert isinstance(cubic.interpolation, jh.CubicInterpolation)


def test_segment():
    rec = _recording()
    part = rec.segment(0.6, 0.8)
    assert part.num_samples == 21
    assert part.t[0] == pytest.approx(0.6) and part.t[-1] == pytest.approx(0.8)
    np.testing.assert_array_equal(part.u, rec.u[10:31])
    assert rec.segment(None, 0.6).num_samples == 11
    with pytest.raises(RecordingError, match="start < stop"):
        rec.segment(0.8, 0.6)
    with pytest.raises(RecordingError, match="holds 0 sample"):
        rec.segment(5.0, 6.0)


def test_split():
    rec = _recording()
    first, second = rec.split(0.7)
    assert first.num_samples + second.num_samples == rec.num_samples
    assert first.num_samples == 71
    assert first.t[-1] < second.t[0]
    np.testing.assert_array_equal(second.y, rec.y[71:])
    with pytest.raises(RecordingError, match="strictly between"):
        rec.split(1.0)
    with pytest.raises(RecordingError, match="at least 2"):
        rec.split(0.001)


def test_resample_method():
    rec = _recording()
    coarse = rec.resample(0.02)
    assert coarse.num_samples == 51
    assert coarse.dt == pytest.approx(0.02)
    np.testing.assert_allclose(coarse.u, rec.u[::2], atol=1e-12)
    fine = rec.resample(0.005)
    assert fine.num_samples == 201
    np.testing.assert_allclose(fine.u[1::2], (rec.u[:-1] + rec.u[1:]) / 2, atol=1e-12)
    with pytest.raises(RecordingError, match="positive"):
        rec.resample(-1.0)
    with pytest.raises(RecordingError, match="smaller dt"):
        rec.resample(5.0)


def test_require_samples():
    rec = _recording()
    rec.require_samples(101)
    with pytest.raises(RecordingError, match="has 101 samples; the swarm needs at"):
        rec.require_samples(500, what="the swarm")


def test_with_output():
    rec = _recording(output_unit="m")
    other = rec.with_output(np.zeros(101))
    np.testing.assert_array_equal(other.y, 0.0)
    np.testing.assert_array_equal(other.u, rec.u)
    assert other.output_unit == "m" and other.name == "rec"
    with pytest.raises(RecordingError, match="length mismatch"):
        rec.with_output(np.zeros(5))


# --------------------------------------------------------------------------- I/O


@pytest.mark.parametrize("suffix", [".csv", ".npz", ".mat"])
def test_round_trip(tmp_path, suffix):
    rec = _recording(input_unit="V", output_unit="um")
    path = tmp_path / f"rec{suffix}"  # CSV keeps no name: the stem becomes it
    rec.save(path)
    back = Recording.load(path)
    _assert_same(rec, back)


@pytest.mark.parametrize("suffix", [".csv", ".npz", ".mat"])
def test_round_trip_named_columns(tmp_path, suffix):
    rec = Recording(
        *_arrays(),
        name="stage",
        input_name="voltage",
        output_name="displacement",
        input_unit="V",
    )
    path = tmp_path / f"stage{suffix}"
    rec.save(path)
    with pytest.raises(RecordingError, match="available"):
        Recording.load(path)
    back = Recording.load(path, input="voltage", output="displacement")
    _assert_same(rec, back)


def test_csv_header_format(tmp_path):
    path = tmp_path / "rec.csv"
    _recording(input_unit="V").save(path)
    assert path.read_text().splitlines()[0] == "t [s],u [V],y"


def test_save_refuses_overwrite(tmp_path):
    rec = _recording()
    path = tmp_path / "rec.npz"
    rec.save(path)
    with pytest.raises(FileExistsError, match="overwrite=True") as info:
        rec.save(path)
    assert str(path) in str(info.value)
    rec.with_output(np.zeros(101)).save(path, overwrite=True)
    assert np.all(Recording.load(path).y == 0)


def test_save_unknown_extension(tmp_path):
    with pytest.raises(RecordingError, match=r"\.xlsx"):
        _recording().save(tmp_path / "rec.xlsx")


def test_save_mat_invalid_variable_name(tmp_path):
    rec = Recording(*_arrays(), input_name="drive voltage")
    with pytest.raises(RecordingError, match="MAT variable name"):
        rec.save(tmp_path / "rec.mat")


def test_headerless_csv_with_empty_first_column(tmp_path):
    path = tmp_path / "piezo.csv"
    path.write_text(",0,-1.61,0\n,0.0002,-1.7,1.5\n,0.0004,-1.65,3.0\n")
    rec = Recording.load(path, time=1, input=3, output=2, header=False)
    np.testing.assert_allclose(rec.t, [0, 0.0002, 0.0004])
    np.testing.assert_allclose(rec.u, [0, 1.5, 3.0])
    np.testing.assert_allclose(rec.y, [-1.61, -1.7, -1.65])
    assert rec.name == "piezo"
    with pytest.raises(RecordingError, match=r"line 1, column 0 is empty"):
        Recording.load(path, time=0, input=3, output=2, header=False)


def test_headerless_csv_needs_indices(tmp_path):
    path = tmp_path / "plain.csv"
    path.write_text("0,0,1\n1,1,2\n")
    with pytest.raises(RecordingError, match="header=False"):
        Recording.load(path, header=False)


def test_missing_header_hint(tmp_path):
    path = tmp_path / "plain.csv"
    path.write_text("0,0,1\n1,1,2\n2,0,1\n")
    with pytest.raises(RecordingError, match="no header"):
        Recording.load(path)


def test_whitespace_txt_with_header(tmp_path):
    path = tmp_path / "rec.txt"
    path.write_text("time force disp\n0 0 1\n0.5 2 2\n1.0 1 3\n")
    rec = Recording.load(path, time="time", input="force", output="disp")
    assert rec.dt == pytest.approx(0.5)
    assert rec.input_name == "force" and rec.output_name == "disp"


def test_load_missing_file(tmp_path):
    path = tmp_path / "nothing.csv"
    with pytest.raises(FileNotFoundError) as info:
        Recording.load(path)
    assert str(path) in str(info.value)


def test_load_empty_file(tmp_path):
    path = tmp_path / "empty.csv"
    path.write_text("")
    with pytest.raises(RecordingError, match="empty"):
        Recording.load(path)


def test_load_header_only(tmp_path):
    path = tmp_path / "head.csv"
    path.write_text("t,u,y\n")
    with pytest.raises(RecordingError, match="no data rows"):
        Recording.load(path)


def test_load_missing_column_lists_available(tmp_path):
    path = tmp_path / "rec.csv"
    path.write_text("time,u,y\n0,0,0\n1,1,1\n")
    with pytest.raises(RecordingError, match=r"no column 't'.*'time', 'u', 'y'"):
        Recording.load(path)


def test_load_index_out_of_range(tmp_path):
    path = tmp_path / "rec.csv"
    path.write_text("0,0,0\n1,1,1\n")
    with pytest.raises(RecordingError, match="out of range"):
        Recording.load(path, time=0, input=1, output=5, header=False)


def test_load_non_numeric_cell(tmp_path):
    path = tmp_path / "rec.csv"
    path.write_text("t,u,y\n0,0,0\n1,abc,1\n2,0,2\n")
    with pytest.raises(RecordingError, match=r"line 3, column 'u' \(index 1\)"):
        Recording.load(path)


def test_load_short_row(tmp_path):
    path = tmp_path / "rec.csv"
    path.write_text("t,u,y\n0,0,0\n1,1\n")
    with pytest.raises(RecordingError, match="line 3 has 2 cells"):
        Recording.load(path)


def test_load_validation_error_names_file(tmp_path):
    path = tmp_path / "rec.csv"
    path.write_text("t,u,y\n0,0,0\n1,0,1\n2,0,2\n")
    with pytest.raises(RecordingError, match="nothing excites") as info:
        Recording.load(path)
    assert str(path) in str(info.value)


def test_load_resample(tmp_path):
    path = tmp_path / "rec.csv"
    path.write_text("t,u,y\n0,0,0\n1,1,1\n3,3,3\n4,4,4\n")
    with pytest.raises(RecordingError, match="resample=True"):
        Recording.load(path)
    rec = Recording.load(path, resample=True)
    np.testing.assert_allclose(rec.t, [0, 4 / 3, 8 / 3, 4])
    np.testing.assert_allclose(rec.u, rec.t)


def test_load_unknown_extension(tmp_path):
    path = tmp_path / "rec.xlsx"
    path.write_text("")
    with pytest.raises(RecordingError, match="unknown file type"):
        Recording.load(path)


def test_load_npz_missing_key(tmp_path):
    path = tmp_path / "rec.npz"
    t, u, y = _arrays()
    np.savez(path, time=t, u=u, y=y)
    with pytest.raises(RecordingError, match=r"no array 't'.*'time', 'u', 'y'"):
        Recording.load(path)
    assert Recording.load(path, time="time").num_samples == 101


def test_load_npz_rejects_index(tmp_path):
    path = tmp_path / "rec.npz"
    np.savez(path, t=np.arange(3.0))
    with pytest.raises(RecordingError, match="by key name"):
        Recording.load(path, time=0)


def test_load_npz_empty(tmp_path):
    path = tmp_path / "rec.npz"
    np.savez(path)
    with pytest.raises(RecordingError, match="empty"):
        Recording.load(path)


def test_load_mat_column_and_row_vectors(tmp_path):
    path = tmp_path / "rec.mat"
    t, u, y = _arrays()
    scipy.io.savemat(path, {"t": t[:, None], "u": u[None, :], "y": y[:, None]})
    rec = Recording.load(path)
    np.testing.assert_array_equal(rec.u, u)
    assert rec.name == "rec"


def test_load_mat_multichannel(tmp_path):
    path = tmp_path / "rec.mat"
    t, u, y = _arrays()
    scipy.io.savemat(path, {"t": t, "u": np.stack([u, u], 1), "y": y})
    with pytest.raises(RecordingError, match="single channel"):
        Recording.load(path)


@pytest.mark.parametrize("suffix", [".csv", ".npz", ".mat"])
def test_load_name(tmp_path, suffix):
    path = tmp_path / f"file{suffix}"
    _recording().save(path)
    assert Recording.load(path).name == ("file" if suffix == ".csv" else "rec")
    assert Recording.load(path, name="other").name == "other"


def _triangle(peaks, per_leg=20):
    points = [0.0, *peaks]
    legs = [np.linspace(a, b, per_leg + 1)[1:] for a, b in zip(points[:-1], points[1:])]
    return np.concatenate([[0.0], *legs])


def test_quasi_static_pseudo_time_and_errors():
    x = _triangle([1, -1, 2, -2])
    r = jh.Recording.quasi_static(x, 3 * x, name="q", input_unit="mm", output_unit="kN")
    np.testing.assert_array_equal(r.t, np.arange(x.size))
    assert (r.time_unit, r.input_name, r.output_name) == (
        "sample",
        "displacement",
        "force",
    )
    assert jh.Recording.quasi_static(x, x, pseudo_dt=0.02).dt == pytest.approx(0.02)
    with pytest.raises(
        jh.RecordingError, match="displacement has 81 samples but force has 80"
    ):
        jh.Recording.quasi_static(x, x[:-1])
    with pytest.raises(jh.RecordingError, match="pseudo_dt must be positive"):
        jh.Recording.quasi_static(x, x, pseudo_dt=-1)


def test_reversals_exact_and_robust_to_noise():
    x = _triangle([1, -1, 2, -2, 3])
    r = jh.Recording.quasi_static(x, x)
    np.testing.assert_array_equal(r.reversals(), [20, 40, 60, 80])
    noisy = x + 0.01 * np.random.default_rng(0).standard_normal(x.size)
    found = jh.Recording.quasi_static(noisy, x).reversals()
    assert found.size == 4 and np.all(np.abs(found - [20, 40, 60, 80]) <= 2)
    rough = x + 0.05 * np.random.default_rng(1).standard_normal(x.size)
    assert jh.Recording.quasi_static(rough, x).reversals(tolerance=0).size > 4
    with pytest.raises(jh.RecordingError, match=r"tolerance must lie in \[0, 1\)"):
        r.reversals(tolerance=1.5)


def test_load_without_time(tmp_path):
    path = tmp_path / "two.txt"
    path.write_text("0 0\n1 2\n2 3\n1 1\n")
    r = jh.Recording.load(path, time=None)
    np.testing.assert_array_equal(r.u, [0, 1, 2, 1])
    np.testing.assert_array_equal(r.t, [0, 1, 2, 3])
    named = tmp_path / "named.csv"
    named.write_text("d [mm],F [kN]\n0,0\n1,2\n2,3\n")
    r = jh.Recording.load(named, time=None, header=True, input="d", output="F")
    assert (r.input_unit, r.output_unit) == ("mm", "kN")
    for content, message in (
        ("0 0\n1 2\n2\n", "different lengths"),
        ("0 0 0\n1 2 1\n", "has 3 columns"),
        ("0\n1\n", "has one column"),
    ):
        path.write_text(content)
        with pytest.raises(jh.RecordingError, match=message):
            jh.Recording.load(path, time=None)
    (tmp_path / "x.npz").write_bytes(b"")
    with pytest.raises(jh.RecordingError, match="two-column .csv/.txt"):
        jh.Recording.load(tmp_path / "x.npz", time=None)
