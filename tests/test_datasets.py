from pathlib import Path

import numpy as np
import pytest

import jaxhyst as jh
from jaxhyst._datasets import STRUCTURAL_TESTS, load_structural_test


def _data_dir() -> Path:
    return jh.datasets.default_data_dir()


needs_data = pytest.mark.skipif(
    not (_data_dir() / "piezo_actuator_smarthysteresis").is_dir()
    or not (_data_dir() / "bouc_wen_benchmark").is_dir(),
    reason="shared data directory not available (set JAXHYST_DATA_DIR)",
)


@pytest.fixture(scope="module")
def piezo():
    return jh.datasets.load_piezo_actuator()


@pytest.fixture(scope="module")
def benchmark():
    return jh.datasets.load_bouc_wen_benchmark()


def test_default_data_dir_env(monkeypatch, tmp_path):
    monkeypatch.setenv("JAXHYST_DATA_DIR", str(tmp_path))
    assert jh.datasets.default_data_dir() == tmp_path


def test_default_data_dir_fallback(monkeypatch, tmp_path):
    monkeypatch.delenv("JAXHYST_DATA_DIR", raising=False)
    repo_data = (Path(jh.__file__).resolve().parents[1] / "../shared/data").resolve()
    work = tmp_path / "project" / "work"
    work.mkdir(parents=True)
    monkeypatch.chdir(work)  # ./../shared/data does not exist yet
    assert jh.datasets.default_data_dir() == repo_data
    local = tmp_path / "project" / "shared" / "data"
    local.mkdir(parents=True)
    assert jh.datasets.default_data_dir() == local.resolve()


def test_missing_piezo_message(tmp_path):
    with pytest.raises(FileNotFoundError) as info:
        jh.datasets.load_piezo_actuator(data_dir=tmp_path)
    message = str(info.value)
    assert str(tmp_path / "piezo_actuator_smarthysteresis") in message
    assert "hysteresis_v_150_1hz.csv" in message
    assert "data_dir" in message and "JAXHYST_DATA_DIR" in message
    assert "chandratue/SmartHysteresis" in message


def test_missing_benchmark_message(tmp_path, monkeypatch):
    monkeypatch.setenv("JAXHYST_DATA_DIR", str(tmp_path))
    with pytest.raises(FileNotFoundError) as info:
        jh.datasets.load_bouc_wen_benchmark()
    message = str(info.value)
    assert str(tmp_path / "bouc_wen_benchmark") in message
    assert "data_dir" in message and "JAXHYST_DATA_DIR" in message
    assert "10.4121/12967592" in message and "forgi86/dynonet" in message


@needs_data
def test_piezo(piezo):
    assert isinstance(piezo, jh.Recording)
    assert piezo.name == "piezo_actuator_150V_1Hz"
    assert piezo.num_samples == 50001
    assert piezo.sample_rate == pytest.approx(5000.0)
    assert piezo.duration == pytest.approx(10.0)
    assert (piezo.input_unit, piezo.output_unit, piezo.time_unit) == ("V", "um", "s")
    assert np.max(np.abs(piezo.u)) == pytest.approx(150.0, rel=0.02)
    assert np.max(np.abs(piezo.y)) == pytest.approx(19.7, rel=0.05)
    # The voltage is 0 until t ~ 3.257 s, then steps to about -90 V.
    step = int(np.argmax(np.abs(np.diff(piezo.u)))) + 1
    assert piezo.t[step] == pytest.approx(3.257, abs=1e-3)
    assert np.all(piezo.u[:step] == 0)
    assert piezo.u[step] == pytest.approx(-87.1, abs=1.0)
    assert np.corrcoef(piezo.u[step:], piezo.y[step:])[0, 1] > 0.95


@needs_data
def test_bouc_wen_benchmark(benchmark):
    assert isinstance(benchmark, jh.datasets.BoucWenBenchmark)
    expected = {
        "train": 40960,
        "train_ehh": 40960,
        "test_multisine": 8192,
        "test_sinesweep": 153000,
    }
    for field, n in expected.items():
        rec = getattr(benchmark, field)
        assert isinstance(rec, jh.Recording), field
        assert rec.num_samples == n, field
        assert rec.sample_rate == pytest.approx(750.0), field
        assert rec.t[0] == 0.0 and rec.t[1] == pytest.approx(1 / 750)
        assert (rec.input_unit, rec.output_unit) == ("N", "m"), field
        # Displacements are in metres: RMS ~ 6.6e-4 m.
        assert np.sqrt(np.mean(rec.y**2)) == pytest.approx(6.6e-4, rel=0.05), field
    assert np.sqrt(np.mean(benchmark.test_multisine.u**2)) == pytest.approx(
        50.0, rel=1e-4
    )
    n = np.arange(153000)
    t = n / 750
    sweep = 40 * np.sin(2 * np.pi * (18 * t + t**2 / 12))
    np.testing.assert_allclose(benchmark.test_sinesweep.u, sweep, atol=1e-8)


# ------------------------------------------------------------ structural tests

_STRUCTURAL_DIRS = (
    "structural_cyclic_bwbn_tmcmc",
    "structural_rc_column_gill_sebinoh",
    "structural_timber_cslotboom",
)
needs_structural = pytest.mark.skipif(
    not all((_data_dir() / folder).is_dir() for folder in _STRUCTURAL_DIRS),
    reason="structural data sets not available (set JAXHYST_DATA_DIR)",
)

# name: (samples, (min u, max u), (min y, max y), units, reversals), from the data
# READMEs (timber_clt_wall without its 8420-sample lead-in). The reversal counts
# were checked on plots of the displacement histories: e.g. timber_clt_wall runs 10
# amplitudes x 3 cycles (60 reversals, the last at the record's end), chiu repeats
# small cycles between its large ones.
_STRUCTURAL = {
    "daniel": (380, (-7.2, 7.2), (-13, 13), ("mm", "kN"), 10),
    "gill": (627, (-34, 34), (-696, 657), ("mm", "kN"), 16),
    "kunnath": (1326, (-28.7, 27.8), (-0.79, 0.81), ("mm", "kN"), 18),
    "chiu": (2671, (-307, 330), (-185, 175), ("mm", "kN"), 125),
    "sharma": (4456, (-30.5, 30.6), (-31.7, 31.3), ("mm", "kN"), 90),
    "gill_sebinoh": (481, (-0.0307, 0.0307), (-0.41, 0.42), ("m", "g"), 12),
    "timber_clt_wall": (861, (-0.145, 0.182), (-73.8, 90.7), ("m", "kN"), 59),
    "timber_steel_plate": (33028, (-84.6, 84.5), (-52.5, 51.4), ("mm", "kN"), 56),
}


def test_structural_names_and_errors(tmp_path):
    assert STRUCTURAL_TESTS == tuple(_STRUCTURAL)
    with pytest.raises(ValueError, match="unknown test 'bogus'; choose from 'daniel'"):
        load_structural_test("bogus")
    for name, fragments in (
        ("chiu", ("displ_chiu.txt", "diegoandresalvarez/BWBN_TMCMC")),
        ("gill_sebinoh", ("experimental data.mat", "sebin-oh/Bouc-Wen-class-model")),
        ("timber_clt_wall", ("TS1_Experiment_Shear.csv", "cslotboom/hysteresis")),
        ("timber_steel_plate", ("SPC1.csv", "cslotboom/hysteresis")),
    ):
        with pytest.raises(FileNotFoundError) as info:
            load_structural_test(name, data_dir=tmp_path)
        message = str(info.value)
        assert all(fragment in message for fragment in fragments), message
        assert "JAXHYST_DATA_DIR" in message and str(tmp_path) in message


def test_structural_damaged_files(tmp_path):
    folder = tmp_path / "structural_cyclic_bwbn_tmcmc"
    folder.mkdir()
    (folder / "displ_daniel.txt").write_text("0\n1\n2\n")
    (folder / "load_kN_daniel.txt").write_text("0\nnan\n2\n")
    with pytest.raises(ValueError, match="line 2 holds 'nan'.*damaged"):
        load_structural_test("daniel", data_dir=tmp_path)
    (folder / "load_kN_daniel.txt").write_text("0\n1\n")
    with pytest.raises(jh.RecordingError, match="3 samples but force has 2"):
        load_structural_test("daniel", data_dir=tmp_path)
    # The timber files: rows with a bad cell are dropped, with a warning.
    folder = tmp_path / "structural_timber_cslotboom"
    folder.mkdir()
    rows = ["F,d", "kN,mm", "0,0", "1,2", "x,3", "2,nan", "", "3,-1", "4,1"]
    (folder / "SPC1.csv").write_text("\n".join(rows) + "\n")
    with pytest.warns(UserWarning, match="dropped 2 row"):
        recording = load_structural_test("timber_steel_plate", data_dir=tmp_path)
    np.testing.assert_array_equal(recording.u, [0, 2, -1, 1])
    np.testing.assert_array_equal(recording.y, [0, 1, 3, 4])


@needs_structural
@pytest.mark.parametrize("name", list(_STRUCTURAL))
def test_structural_tests(name):
    samples, u_range, y_range, units, reversals = _STRUCTURAL[name]
    recording = load_structural_test(name)
    assert recording.name == name
    assert recording.num_samples == samples
    assert (recording.input_unit, recording.output_unit) == units
    assert (recording.input_name, recording.output_name) == ("displacement", "force")
    np.testing.assert_array_equal(recording.t, np.arange(samples))
    assert recording.time_unit == "sample"
    for values, (lo, hi) in ((recording.u, u_range), (recording.y, y_range)):
        assert values.min() == pytest.approx(lo, rel=0.02)
        assert values.max() == pytest.approx(hi, rel=0.02)
    found = recording.reversals()
    print(f"{name}: {found.size} reversals, {found.size // 2} cycles")
    assert found.size == reversals
    # Reversals alternate: maxima and minima of the displacement in turn.
    signs = np.sign(np.diff(recording.u[found]))
    assert np.all(signs[1:] == -signs[:-1])


@needs_structural
def test_timber_clt_wall_drops_the_quiet_lead_in():
    recording = load_structural_test("timber_clt_wall")
    path = _data_dir() / "structural_timber_cslotboom" / "TS1_Experiment_Shear.csv"
    raw = np.loadtxt(path, delimiter=",")
    assert raw.shape == (9281, 2)
    np.testing.assert_array_equal(recording.u, raw[8420:, 0])
    np.testing.assert_allclose(recording.y, raw[8420:, 1] / 1000, rtol=1e-15)
    # Before the cut the displacement sits at -3.1 mm within +-0.2 mm, then the
    # cycles buried in that noise start.
    assert np.ptp(raw[:8300, 0]) < 0.5e-3
    assert np.ptp(recording.u) > 0.3


@pytest.mark.skipif(
    not (_data_dir() / "mr_damper_labcontrol_utfpr").is_dir(),
    reason="Labcontrol MR damper tests not available (set JAXHYST_DATA_DIR)",
)
def test_mr_damper_sine_tests():
    rec = jh.datasets.load_mr_damper_sine("ensaio1.1")
    assert rec.num_samples == 3001 and rec.dt == pytest.approx(0.01)
    assert (rec.input_unit, rec.output_unit) == ("mm", "N")
    assert rec.input_names == ("displacement",)
    # The displacement is the file's first column, the force its third.
    assert 20 < np.ptp(rec.u) < 30 and 200 < np.ptp(rec.y) < 300


def test_mr_damper_sine_names_and_missing_files(tmp_path):
    with pytest.raises(ValueError, match="file stem"):
        jh.datasets.load_mr_damper_sine("data/ensaio1.1.mat")
    with pytest.raises(FileNotFoundError) as info:
        jh.datasets.load_mr_damper_sine("ensaio1.1", data_dir=tmp_path)
    message = str(info.value)
    assert (
        "labcontrol-data/mr-damper" in message
        and "mr_damper_labcontrol_utfpr" in message
    )
