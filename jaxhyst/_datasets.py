"""Loaders for the real data sets used by the examples, tests and benchmarks.

The data are not shipped with the package. They are looked up in `data_dir` (default:
`default_data_dir()`, which honours the `JAXHYST_DATA_DIR` environment variable); a
missing file raises `FileNotFoundError` saying where to get it.
"""

import csv
import math
import os
import warnings
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


# ------------------------------------------------------------ structural tests

_BWBN_DIR = Path("structural_cyclic_bwbn_tmcmc")
_BWBN_SOURCE = "download it from folder data/ of GitHub diegoandresalvarez/BWBN_TMCMC"
_GILL_FILE = Path("structural_rc_column_gill_sebinoh") / "experimental data.mat"
_GILL_SOURCE = (
    "download 'Example/experimental data.mat' from GitHub sebin-oh/Bouc-Wen-class-model"
)
_TIMBER_DIR = Path("structural_timber_cslotboom")
_TIMBER_CLT_SOURCE = (
    "download 'examples/02 Basic Usage/2.2 Hysteresis with Noisey Data/"
    "TS1_Experiment_Shear.csv' from GitHub cslotboom/hysteresis"
)
_TIMBER_SPC_SOURCE = (
    "download 'examples/WTCE Examples/SPC1.csv' from GitHub cslotboom/hysteresis"
)
# The first 8420 samples of TS1_Experiment_Shear.csv: the actuator at rest and the
# first cycles, below the displacement noise (upstream's example drops them too).
_TIMBER_CLT_LEAD_IN = 8420

STRUCTURAL_TESTS = (
    "daniel",
    "gill",
    "kunnath",
    "chiu",
    "sharma",
    "gill_sebinoh",
    "timber_clt_wall",
    "timber_steel_plate",
)


def _read_column(path: Path, source: str) -> np.ndarray:
    """One number per line; a damaged file is an error (its partner file would no
    longer line up)."""
    with open(path, encoding="utf-8") as file:
        lines = file.read().splitlines()
    values = []
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        try:
            value = float(line)
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            raise ValueError(
                f"{str(path)!r} line {number} holds {line.strip()!r}, not a finite "
                f"number; the file is damaged: {source} again."
            )
        values.append(value)
    return np.asarray(values, dtype=np.float64)


def _read_rows(path: Path, skip: int, name: str) -> np.ndarray:
    """The two comma-separated columns after `skip` header rows, as an (N, 2) array;
    rows with a missing, non-numeric or non-finite cell are dropped with a warning."""
    with open(path, encoding="utf-8-sig", newline="") as file:
        rows = list(csv.reader(file))[skip:]
    kept, dropped = [], []
    for number, row in enumerate(rows, start=skip + 1):
        try:
            pair = [float(cell) for cell in row[:2]]
        except ValueError:
            pair = []
        if len(pair) == 2 and all(math.isfinite(v) for v in pair):
            kept.append(pair)
        elif any(cell.strip() for cell in row):
            dropped.append(number)
    if dropped:
        warnings.warn(
            f"load_structural_test({name!r}): dropped {len(dropped)} row(s) of "
            f"{str(path)!r} with a missing, non-numeric or non-finite value (the "
            f"first at line {dropped[0]}).",
            stacklevel=4,
        )
    return np.asarray(kept, dtype=np.float64).reshape(-1, 2)


def _bwbn_test(name: str, data_dir) -> Recording:
    displacement = _read_column(
        _locate(data_dir, _BWBN_DIR / f"displ_{name}.txt", _BWBN_SOURCE),
        _BWBN_SOURCE,
    )
    force = _read_column(
        _locate(data_dir, _BWBN_DIR / f"load_kN_{name}.txt", _BWBN_SOURCE),
        _BWBN_SOURCE,
    )
    return Recording.quasi_static(
        displacement, force, name=name, input_unit="mm", output_unit="kN"
    )


def _gill_sebinoh(data_dir) -> Recording:
    data = _mat_variable(_locate(data_dir, _GILL_FILE, _GILL_SOURCE), "data_exp")
    if data.ndim != 2 or data.shape[1] != 2:
        raise ValueError(
            f"load_structural_test('gill_sebinoh'): data_exp has shape {data.shape}, "
            f"expected (N, 2); {_GILL_SOURCE} again."
        )
    return Recording.quasi_static(
        data[:, 0],
        data[:, 1],
        name="gill_sebinoh",
        input_unit="m",
        output_unit="g",
    )


def _timber_clt_wall(data_dir) -> Recording:
    path = _locate(
        data_dir, _TIMBER_DIR / "TS1_Experiment_Shear.csv", _TIMBER_CLT_SOURCE
    )
    data = _read_rows(path, 0, "timber_clt_wall")[_TIMBER_CLT_LEAD_IN:]
    return Recording.quasi_static(
        data[:, 0],
        data[:, 1] / 1000.0,
        name="timber_clt_wall",
        input_unit="m",
        output_unit="kN",
    )


def _timber_steel_plate(data_dir) -> Recording:
    path = _locate(data_dir, _TIMBER_DIR / "SPC1.csv", _TIMBER_SPC_SOURCE)
    data = _read_rows(path, 2, "timber_steel_plate")
    return Recording.quasi_static(
        data[:, 1],
        data[:, 0],
        name="timber_steel_plate",
        input_unit="mm",
        output_unit="kN",
    )


_MR_DAMPER_DIR = Path("mr_damper_dyke_nees")
_MR_DAMPER_SOURCE = (
    "download Dataset/<name>_converted.csv from GitHub Abhay3757/PSO-Optimized-Dual-"
    "Attention-LSTM-for-MR-Damper-Force-Prediction (S. Dyke, NEES-2012-1158, "
    "DOI 10.4231/D3V11VM6X)"
)
_MR_DAMPER_RATE = 3004.8
MR_DAMPER_TESTS = ("ranran_50", "ransim_u")
"""The names `load_mr_damper` accepts."""


def load_mr_damper(
    name: str, *, data_dir: str | os.PathLike | None = None
) -> Recording:
    """A measured white-noise test of a prototype MR damper (S. Dyke,
    NEES-2012-1158, recorded 1994-1996): displacement [cm] and command voltage [V]
    (the further input "command") -> force [N], at 3004.8 Hz.

    - "ranran_50": 74068 samples (24.6 s), 0-50 Hz white-noise displacement and a
      random command between -0.43 and 2.69 V.
    - "ransim_u": 60096 samples (20.0 s), the upstream "simulation" test class
      (command filtered).

    The files' time column is rounded to 0.1 ms, so the time is rebuilt on the
    stated 3004.8 Hz grid (t = k / 3004.8). Raises `ValueError` for an unknown
    name and `FileNotFoundError`, saying where to get the file, when it is missing.
    """
    if name not in MR_DAMPER_TESTS:
        raise ValueError(
            f"load_mr_damper: unknown test {name!r}; choose from "
            f"{', '.join(map(repr, MR_DAMPER_TESTS))}."
        )
    path = _locate(
        data_dir, _MR_DAMPER_DIR / f"{name}_converted.csv", _MR_DAMPER_SOURCE
    )
    raw = Recording.load(path, input=["D", "Y"], output="F", resample=True)
    return Recording(
        np.arange(raw.num_samples) / _MR_DAMPER_RATE,
        raw.u,
        raw.y,
        name=f"mr_damper_{name}",
        input_name="displacement",
        output_name="force",
        input_unit="cm",
        output_unit="N",
        more_inputs={"command": raw.more_input("Y")},
        more_input_units={"command": "V"},
    )


_SINE_DAMPER_DIR = Path("mr_damper_labcontrol_utfpr")
_SINE_DAMPER_SOURCE = (
    "download data/<name>.mat from GitHub labcontrol-data/mr-damper (A. N. Vargas, "
    "Zenodo doi:10.5281/zenodo.4445334)"
)


def load_mr_damper_sine(
    name: str, *, data_dir: str | os.PathLike | None = None
) -> Recording:
    """A measured sine test of an MR damper on a small shaking table (Labcontrol,
    UTFPR; MIT licence): displacement [mm] -> force [N], `name` the file's stem
    (e.g. "ensaio1.1"; 751 to 3001 samples at 50-100 Hz, 0.8-2.4 Hz sines).

    The coil's voltage or current is not recorded (the tests ran at undocumented
    settings), so the recording has one input; for the damper diagnosis, add the
    setting as a constant command (`rec.with_input("command", 0.0)`): the diagnosis
    then says that the field's effects cannot show on such a record. The files'
    velocity column is not used (the model derives it from the displacement).
    Raises `ValueError` for a name with a path in it and `FileNotFoundError`,
    saying where to get the file, when it is missing."""
    if not name or Path(name).name != name or name.endswith(".mat"):
        raise ValueError(
            f"load_mr_damper_sine: name {name!r} must be a file stem such as "
            "'ensaio1.1' (no folder, no '.mat')."
        )
    import scipy.io

    path = _locate(data_dir, _SINE_DAMPER_DIR / f"{name}.mat", _SINE_DAMPER_SOURCE)
    data = scipy.io.loadmat(path, variable_names=["x_F", "Ts"])
    columns, step = np.asarray(data["x_F"], float), float(np.ravel(data["Ts"])[0])
    return Recording(
        step * np.arange(columns.shape[0]),
        columns[:, 0],
        columns[:, 2],
        name=f"mr_damper_sine_{name}",
        input_name="displacement",
        output_name="force",
        input_unit="mm",
        output_unit="N",
    )


def load_structural_test(
    name: str, *, data_dir: str | os.PathLike | None = None
) -> Recording:
    """A measured quasi-static cyclic test: imposed displacement -> restoring force,
    as `Recording.quasi_static` (pseudo time t = sample index; `name` is the
    recording's name). `name` is one of `STRUCTURAL_TESTS`:

    - "daniel": lab test by D. Bedoya-Ruiz (specimen not described upstream), 380
      points, +-7.2 mm, +-13 kN. Source of this and the next four: GitHub
      diegoandresalvarez/BWBN_TMCMC (Ortiz, Alvarez & Bedoya-Ruiz 2015, Computers &
      Structures 146), displ_<name>.txt [mm] and load_kN_<name>.txt [kN]; that paper
      identifies degrading, pinching Bouc-Wen-Baber-Noori models on them.
    - "gill": RC column (presumably Gill, Park & Priestley 1979), 627 points,
      +-34 mm, -696..657 kN; stiffness and strength degrade with amplitude.
    - "kunnath": RC test, 1326 points, +-29 mm, +-0.81 "kN" (as labelled; too small
      for the stated 6 kN/mm stiffness, so probably normalised); degrading loops.
    - "chiu": 2671 points, -307..330 mm, +-185 kN; strongly pinched loops.
    - "sharma": 4456 points, +-31 mm, +-32 kN; pinched, degrading loops.
    - "gill_sebinoh": Gill, Park & Priestley (1979) RC column via the PEER
      Structural Performance Database, 481 points, +-0.031 m, lateral load
      normalised by the weight [g] (GitHub sebin-oh/Bouc-Wen-class-model, Oh, Kim &
      Song 2023, variable data_exp); likely the same test as "gill", processed
      differently; degrading loops.
    - "timber_clt_wall": CLT rocking shear wall (R. Ganey, MSc thesis, University of
      Washington 2015), top displacement [m] -> shear force [kN] (the file's N /
      1000), from GitHub cslotboom/hysteresis TS1_Experiment_Shear.csv. Its first
      8420 of 9281 samples (the actuator at rest, then the first cycles buried in
      the displacement noise) are dropped, as upstream's example does, leaving 861;
      strongly pinched (rocking), noisy.
    - "timber_steel_plate": perforated steel-plate connection for CLT walls
      (Drexler, Dires & Tannert, WCTE 2021), 33028 points, +-85 mm, +-52 kN, from
      cslotboom/hysteresis SPC1.csv (2 header rows, force [kN] then displacement
      [mm]); pinched, degrading, with the connection failing in the last cycles.

    Rows of the timber files with a missing, non-numeric or non-finite cell are
    dropped with a warning (the published files have none); the other files must be
    entirely numeric. Raises `ValueError` for an unknown name and
    `FileNotFoundError`, saying where to get the file, when a file is missing.
    """
    if name in ("daniel", "gill", "kunnath", "chiu", "sharma"):
        return _bwbn_test(name, data_dir)
    if name == "gill_sebinoh":
        return _gill_sebinoh(data_dir)
    if name == "timber_clt_wall":
        return _timber_clt_wall(data_dir)
    if name == "timber_steel_plate":
        return _timber_steel_plate(data_dir)
    raise ValueError(
        f"load_structural_test: unknown test {name!r}; choose from "
        f"{', '.join(map(repr, STRUCTURAL_TESTS))}."
    )
