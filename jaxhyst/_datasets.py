"""Loaders for the real data sets used by the examples, tests and benchmarks.

The data are not shipped with the package. They are looked up in `data_dir` (default:
`default_data_dir()`, which honours the `JAXHYST_DATA_DIR` environment variable); a
missing file raises `FileNotFoundError` saying where to get it.
"""

import os
from pathlib import Path

import equinox as eqx
import numpy as np

from ._recording import Recording


_PIEZO_FILE = Path("piezo_actuator_smarthysteresis") / "hysteresis_v_150_1hz.csv"
_PIEZO_SOURCE = (
    "download Data/hysteresis_v_150_1hz.csv from GitHub chandratue/SmartHysteresis"
)
_BW_DIR = Path("bouc_wen_benchmark")
_BW_SOURCE = (
    "get BoucWenFiles.zip from nonlinearbenchmark.org (4TU.ResearchData "
    "doi:10.4121/12967592) for validation/*.mat, and "
    "examples/BW/data/Test signals/train.h5 from GitHub forgi86/dynonet for "
    "training_dynonet/train.h5"
)
_BW_RATE = 750.0


def default_data_dir() -> Path:
    """Where the data sets are looked up: `$JAXHYST_DATA_DIR` if set, else the first
    existing of `./../shared/data` and `<repository root>/../shared/data` (the latter
    is returned even when it does not exist)."""
    env = os.environ.get("JAXHYST_DATA_DIR")
    if env:
        return Path(env).expanduser()
    candidates = (
        Path.cwd() / ".." / "shared" / "data",
        Path(__file__).resolve().parents[1] / ".." / "shared" / "data",
    )
    for candidate in candidates:
        if candidate.is_dir():
            return candidate.resolve()
    return candidates[-1].resolve()


def _locate(data_dir: str | os.PathLike | None, relative: Path, source: str) -> Path:
    root = default_data_dir() if data_dir is None else Path(data_dir)
    path = root / relative
    if not path.is_file():
        raise FileNotFoundError(
            f"data file {str(path)!r} not found; {source} and place it at "
            f"{relative.as_posix()!r} under a data directory, then pass "
            "data_dir=... or set JAXHYST_DATA_DIR to that directory."
        )
    return path


def load_piezo_actuator(*, data_dir: str | os.PathLike | None = None) -> Recording:
    """Measured piezoelectric actuator: voltage [V] -> displacement [um].

    50001 samples at 5 kHz over 10 s (Chandra et al. 2023, GitHub
    chandratue/SmartHysteresis). The voltage is 0 until t = 3.257 s, then steps to
    about -90 V and runs as a 150 V, 1 Hz sine; the step drives a transient.
    """
    path = _locate(data_dir, _PIEZO_FILE, _PIEZO_SOURCE)
    recording = Recording.load(path, time=1, input=3, output=2, header=False)
    return Recording(
        recording.t,
        recording.u,
        recording.y,
        name="piezo_actuator_150V_1Hz",
        input_name="voltage",
        output_name="displacement",
        input_unit="V",
        output_unit="um",
        time_unit="s",
    )


class BoucWenBenchmark(eqx.Module):
    """The Bouc-Wen benchmark (Noel & Schoukens 2016): force [N] -> displacement [m]
    at 750 Hz, all synthetic.

    `train`: multisine estimation record with output noise (40960 samples, dynoNet's
    train.h5). `train_ehh`: another multisine realization (preston1000/EHH), None when
    its file is absent. `test_multisine` (8192 samples, one steady-state period) and
    `test_sinesweep` (153000 samples, from rest): the official noiseless test sets.
    """

    train: Recording
    train_ehh: Recording | None
    test_multisine: Recording
    test_sinesweep: Recording


def _bouc_wen_recording(u: np.ndarray, y: np.ndarray, name: str) -> Recording:
    u = np.asarray(u, dtype=np.float64).ravel()
    y = np.asarray(y, dtype=np.float64).ravel()
    return Recording(
        np.arange(u.shape[0]) / _BW_RATE,
        u,
        y,
        name=name,
        input_name="force",
        output_name="displacement",
        input_unit="N",
        output_unit="m",
        time_unit="s",
    )


def _mat_variable(path: Path, key: str) -> np.ndarray:
    import scipy.io

    return scipy.io.loadmat(path, variable_names=[key])[key]


def load_bouc_wen_benchmark(
    *, data_dir: str | os.PathLike | None = None
) -> BoucWenBenchmark:
    """The Bouc-Wen benchmark training and test records (see `BoucWenBenchmark`).

    Reading train.h5 needs h5py (`pip install h5py` or `pip install jaxhyst[data]`).
    """
    validation = _BW_DIR / "validation"
    tests = {}
    for kind in ("multisine", "sinesweep"):
        u_path = _locate(data_dir, validation / f"uval_{kind}.mat", _BW_SOURCE)
        y_path = _locate(data_dir, validation / f"yval_{kind}.mat", _BW_SOURCE)
        tests[kind] = _bouc_wen_recording(
            _mat_variable(u_path, f"uval_{kind}"),
            _mat_variable(y_path, f"yval_{kind}"),
            f"bouc_wen_test_{kind}",
        )

    train_path = _locate(
        data_dir, _BW_DIR / "training_dynonet" / "train.h5", _BW_SOURCE
    )
    try:
        import h5py
    except ImportError:
        raise ImportError(
            "load_bouc_wen_benchmark: reading train.h5 needs h5py; install it with "
            "`pip install h5py` (or `pip install jaxhyst[data]`)."
        ) from None
    with h5py.File(train_path, "r") as file:
        u = np.asarray(file["multisine/u"])
        y = np.asarray(file["multisine/y"])
        rate = float(np.asarray(file["multisine/fs"]).ravel()[0])
    if rate != _BW_RATE:
        raise ValueError(
            f"load_bouc_wen_benchmark: {str(train_path)!r} says fs = {rate}, expected "
            f"{_BW_RATE}; replace the file with dynoNet's examples/BW train.h5."
        )
    train = _bouc_wen_recording(u, y, "bouc_wen_train_multisine")

    root = default_data_dir() if data_dir is None else Path(data_dir)
    ehh_path = root / _BW_DIR / "training_ehh" / "bouc-wen.mat"
    train_ehh = None
    if ehh_path.is_file():
        train_ehh = _bouc_wen_recording(
            _mat_variable(ehh_path, "u"),
            _mat_variable(ehh_path, "y"),
            "bouc_wen_train_ehh",
        )
    return BoucWenBenchmark(
        train=train,
        train_ehh=train_ehh,
        test_multisine=tests["multisine"],
        test_sinesweep=tests["sinesweep"],
    )
