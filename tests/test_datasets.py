from pathlib import Path

import numpy as np
import pytest

import jaxhyst as jh


def _data_dir() -> Path:
    return jh.default_data_dir()


needs_data = pytest.mark.skipif(
    not (_data_dir() / "piezo_actuator_smarthysteresis").is_dir()
    or not (_data_dir() / "bouc_wen_benchmark").is_dir(),
    reason="shared data directory not available (set JAXHYST_DATA_DIR)",
)


@pytest.fixture(scope="module")
def piezo():
    return jh.load_piezo_actuator()


@pytest.fixture(scope="module")
def benchmark():
    return jh.load_bouc_wen_benchmark()


def test_default_data_dir_env(monkeypatch, tmp_path):
    monkeypatch.setenv("JAXHYST_DATA_DIR", str(tmp_path))
    assert jh.default_data_dir() == tmp_path


def test_default_data_dir_fallback(monkeypatch, tmp_path):
    monkeypatch.delenv("JAXHYST_DATA_DIR", raising=False)
    repo_data = (Path(jh.__file__).resolve().parents[1] / "../shared/data").resolve()
    work = tmp_path / "project" / "work"
    work.mkdir(parents=True)
    monkeypatch.chdir(work)  # ./../shared/data does not exist yet
    assert jh.default_data_dir() == repo_data
    local = tmp_path / "project" / "shared" / "data"
    local.mkdir(parents=True)
    assert jh.default_data_dir() == local.resolve()


def test_missing_piezo_message(tmp_path):
    with pytest.raises(FileNotFoundError) as info:
        jh.load_piezo_actuator(data_dir=tmp_path)
    message = str(info.value)
    assert str(tmp_path / "piezo_actuator_smarthysteresis") in message
    assert "hysteresis_v_150_1hz.csv" in message
    assert "data_dir" in message and "JAXHYST_DATA_DIR" in message
    assert "chandratue/SmartHysteresis" in message


def test_missing_benchmark_message(tmp_path, monkeypatch):
    monkeypatch.setenv("JAXHYST_DATA_DIR", str(tmp_path))
    with pytest.raises(FileNotFoundError) as info:
        jh.load_bouc_wen_benchmark()
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
    assert isinstance(benchmark, jh.BoucWenBenchmark)
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
