"""A battery of odd files and command-line misuses: each ends `jaxhyst` with one line
on stderr, `jaxhyst: error: ...`, naming the file (or the flag) at fault and the fix,
in the command line's words, with exit status 2: no traceback, no warning (pytest
turns warnings into errors), and no fitting (every check comes before it)."""

import codecs
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest

from jaxhyst._cli import main
from jaxhyst._cli._main import build_parser
from jaxhyst._cli._options import load_recordings
from jaxhyst._cli._words import PYTHON_WORDS, cli_words
from jaxhyst._recording import Recording, RecordingError


QUICK = ("--particles", "4", "--iterations", "2")


def _sine_rows(n: int = 40) -> np.ndarray:
    t = np.arange(n) * 0.01
    u = np.sin(2 * np.pi * 2 * t)
    return np.stack([t, u, 0.5 * u + 0.1 * np.cos(2 * np.pi * 2 * t)], axis=1)


def _csv(path: Path, rows: np.ndarray, header: str | None = "t,u,y") -> Path:
    lines = [] if header is None else [header]
    lines += [",".join(f"{x:.17g}" for x in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def _scaled(path: Path, column: int, factor: float) -> Path:
    rows = _sine_rows()
    rows[:, column] *= factor
    return _csv(path, rows)


def _replaced(path: Path, row: int, column: int, cell: str) -> Path:
    rows = [[f"{x:.17g}" for x in r] for r in _sine_rows()]
    rows[row][column] = cell
    path.write_text("t,u,y\n" + "\n".join(",".join(r) for r in rows) + "\n")
    return path


def _truncated_npz(path: Path) -> Path:
    t, u, y = _sine_rows().T
    np.savez(path, t=t, u=u, y=y)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    return path


def _truncated_mat(path: Path) -> Path:
    import scipy.io

    t, u, y = _sine_rows().T
    scipy.io.savemat(path, {"t": t, "u": u, "y": y})
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    return path


def _npz(path: Path) -> Path:
    t, u, y = _sine_rows().T
    np.savez(path, t=t, u=u, y=y)
    return path


class Case(NamedTuple):
    make: Callable[[Path], Path]
    """Writes the file under the folder given; returns its path."""
    argv: Callable[[str], list[str]]
    """The command line, given the file's path."""
    says: tuple[str, ...] = ()
    """What the line must say besides the file's name (lower case)."""


def fit(*options: str) -> Callable[[str], list[str]]:
    return lambda path: ["fit", path, *QUICK, *options]


def diagnose(*options: str) -> Callable[[str], list[str]]:
    return lambda path: ["diagnose", path, *options]


def _rows_text(text: str, name: str) -> Callable[[Path], Path]:
    def make(folder: Path) -> Path:
        path = folder / name
        path.write_text(text)
        return path

    return make


def _rows_bytes(data: bytes, name: str) -> Callable[[Path], Path]:
    def make(folder: Path) -> Path:
        path = folder / name
        path.write_bytes(data)
        return path

    return make


_HEADERLESS = "\n".join(",".join(f"{x:.6g}" for x in r) for r in _sine_rows()) + "\n"
_TWO_COLUMNS = "\n".join(f"{u:.6g},{y:.6g}" for _, u, y in _sine_rows()) + "\n"

CASES: dict[str, Case] = {
    "binary": Case(
        _rows_bytes(bytes(range(256)) * 4 + b"\x87\x00", "scope.csv"),
        fit(),
        ("not a text file",),
    ),
    "utf16-without-mark": Case(
        _rows_bytes("t,u,y\n0,1,2\n".encode("utf-16-le"), "export.csv"),
        fit(),
        ("not a text file",),
    ),
    "utf16-header-without-t": Case(
        _rows_bytes(
            codecs.BOM_UTF16_LE + "time,u,y\n0,0,0\n1,1,1\n".encode("utf-16-le"),
            "utf16.csv",
        ),
        fit(),
        ("no column 't'", "--time"),
    ),
    "latin1-header-without-t": Case(
        _rows_bytes(
            "Zeit [s],Weg [\xb5m],Kraft [N]\n0,0,0\n1,1,2\n".encode("latin-1"),
            "latin1.csv",
        ),
        fit(),
        ("no column 't'", "weg [\xb5m]", "--time"),
    ),
    "bom-decimal-comma": Case(
        _rows_bytes(b"\xef\xbb\xbft;u;y\n0,0;0,5;1,5\n0,1;1,5;2,5\n", "comma.csv"),
        fit(),
        ("'0,0'", "decimal point"),
    ),
    "truncated-npz": Case(lambda f: _truncated_npz(f / "cut.npz"), fit(), ("npz",)),
    "csv-named-npz": Case(
        lambda f: _csv(f / "renamed.npz", _sine_rows()), fit(), ("npz",)
    ),
    "not-a-mat-file": Case(_rows_text("t,u,y\n0,1,2\n", "fake.mat"), fit(), (".mat",)),
    "truncated-mat": Case(lambda f: _truncated_mat(f / "cut.mat"), fit(), (".mat",)),
    "empty": Case(_rows_text("", "empty.csv"), fit(), ("empty",)),
    "comments-only": Case(_rows_text("# t,u,y\n#\n", "notes.csv"), fit(), ("empty",)),
    "header-only": Case(_rows_text("t,u,y\n", "head.csv"), fit(), ("no data rows",)),
    "huge-values": Case(
        lambda f: _scaled(f / "huge.csv", 1, 1e200), fit(), ("too large", "units")
    ),
    "huge-output": Case(
        lambda f: _scaled(f / "hugey.csv", 2, 1e200), diagnose(), ("too large",)
    ),
    "tiny-input": Case(
        lambda f: _scaled(f / "tiny.csv", 1, 1e-300), fit(), ("too small", "units")
    ),
    "constant-output": Case(
        lambda f: _replaced_column(f / "flat.csv", 2, 3.0),
        fit(),
        ("output is constant", "--output"),
    ),
    "zero-output": Case(
        lambda f: _replaced_column(f / "zero.csv", 2, 0.0),
        diagnose("--model", "bouc-wen"),
        ("output is constant",),
    ),
    "constant-input": Case(
        lambda f: _replaced_column(f / "still.csv", 1, 1.0),
        fit(),
        ("constant", "--input"),
    ),
    "nan": Case(lambda f: _replaced(f / "nan.csv", 5, 2, "nan"), fit(), ("nan",)),
    "inf": Case(lambda f: _replaced(f / "inf.csv", 5, 1, "-inf"), fit(), ("inf",)),
    "non-numeric": Case(
        lambda f: _replaced(f / "words.csv", 3, 1, "n/a"), fit(), ("'n/a'", "line 5")
    ),
    "empty-cell": Case(
        lambda f: _replaced(f / "hole.csv", 3, 2, ""), fit(), ("empty", "line 5")
    ),
    "ragged": Case(
        _rows_text("t,u,y\n0,0,0\n0.01,0.5\n0.02,1,1\n", "ragged.csv"),
        fit(),
        ("line 3", "missing"),
    ),
    "time-backwards": Case(
        lambda f: _replaced(f / "back.csv", 7, 0, "0.01"),
        fit(),
        ("not strictly increasing", "sort"),
    ),
    "time-repeated": Case(
        lambda f: _replaced(f / "twice.csv", 7, 0, "0.06"),
        fit(),
        ("not strictly increasing",),
    ),
    "time-non-uniform": Case(
        lambda f: _replaced(f / "jitter.csv", 7, 0, "0.0705"),
        fit(),
        ("not uniformly sampled", "resample"),
    ),
    "one-sample": Case(_rows_text("t,u,y\n0,1,2\n", "short.csv"), fit(), ("sample",)),
    "too-few-to-fit": Case(
        lambda f: _csv(f / "brief.csv", _sine_rows(12)),
        fit(),
        ("12 samples", "at least 20"),
    ),
    "too-few-to-diagnose": Case(
        lambda f: _csv(f / "brief.csv", _sine_rows(40)),
        diagnose("--model", "bouc-wen"),
        ("40 samples", "at least 100"),
    ),
    "headerless-two-columns": Case(
        _rows_text(_TWO_COLUMNS, "loop.csv"),
        diagnose("--model", "bouc-wen"),
        ("no header", "--no-time"),
    ),
    "headerless-three-columns": Case(
        _rows_text(_HEADERLESS, "raw.txt"), fit(), ("no header", "--no-header")
    ),
    "no-header-two-columns": Case(
        _rows_text(_TWO_COLUMNS, "pairs.csv"),
        fit("--no-header"),
        ("--output 2", "--no-time"),
    ),
    "missing-file": Case(lambda f: f / "nowhere.csv", fit(), ("does not exist",)),
    "folder-as-file": Case(lambda f: f, fit(), ("folder",)),
    "missing-input-column": Case(
        lambda f: _csv(f / "plain.csv", _sine_rows()),
        fit("--input", "v"),
        ("no column 'v'", "--input"),
    ),
    "input-index-out-of-range": Case(
        lambda f: _csv(f / "plain.csv", _sine_rows(), header=None),
        fit("--no-header", "--input", "7"),
        ("--input 7", "out of range"),
    ),
    "no-time-with-three-columns": Case(
        lambda f: _csv(f / "wide.csv", _sine_rows(), header=None),
        fit("--no-time"),
        ("3 columns", "exactly two"),
    ),
    "no-time-with-npz": Case(
        lambda f: _npz(f / "arrays.npz"), fit("--no-time"), ("--no-time", ".csv")
    ),
    "npz-index-column": Case(
        lambda f: _npz(f / "arrays.npz"), fit("--input", "1"), ("--input 1", "name")
    ),
    "npz-missing-key": Case(
        lambda f: _npz(f / "arrays.npz"),
        fit("--output", "force"),
        ("no array 'force'", "--output"),
    ),
    "unknown-suffix": Case(
        _rows_text("t,u,y\n", "book.xlsx"), fit(), ("'.xlsx'", ".csv")
    ),
    "window-past-the-end": Case(
        lambda f: _csv(f / "plain.csv", _sine_rows()),
        fit("--start", "5"),
        ("--start 5",),
    ),
    "window-of-constant-output": Case(
        lambda f: _flat_tail(f / "tail.csv"),
        fit("--start", "0.25"),
        ("output is constant (1) over the window --start/--end",),
    ),
    "evaluate-on-odd-file": Case(
        _rows_bytes(b"\x00\x01\x02", "blob.csv"),
        lambda path: ["evaluate", _model_file(Path(path).parent), path],
        ("not a text file",),
    ),
    "diagnose-two-files-one-odd": Case(
        _rows_text("t,u,y\n", "second.csv"),
        lambda path: [
            "diagnose",
            str(_csv(Path(path).parent / "first.csv", _sine_rows())),
            path,
        ],
        ("no data rows",),
    ),
}


def _replaced_column(path: Path, column: int, value: float) -> Path:
    rows = _sine_rows()
    rows[:, column] = value
    return _csv(path, rows)


def _flat_tail(path: Path) -> Path:
    rows = _sine_rows()
    rows[20:, 2] = 1.0
    return _csv(path, rows)


def _model_file(folder: Path) -> str:
    import jaxhyst as jh

    path = folder / "model.json"
    jh.save_model(jh.PiezoBoucWen.paper_table4(3), path)
    return str(path)


def _check_line(capsys, status: int, name: str, says: tuple[str, ...]) -> str:
    captured = capsys.readouterr()
    lines = [line for line in captured.err.splitlines() if line.strip()]
    assert status == 2, captured.err
    assert len(lines) == 1, captured.err
    line = lines[0]
    assert line.startswith("jaxhyst: error: "), line
    assert name in line, line
    assert "Traceback" not in captured.err
    for word in PYTHON_WORDS:
        assert word not in line, line
    for phrase in says:
        assert phrase in line.lower(), line
    return line


@pytest.mark.parametrize("case", list(CASES), ids=list(CASES))
def test_odd_file_gives_one_line(case, tmp_path, capsys):
    spec = CASES[case]
    path = spec.make(tmp_path)
    status = main(spec.argv(str(path)))
    _check_line(capsys, status, path.name, spec.says)


def test_wrong_model_names_the_choices(tmp_path, capsys):
    path = _csv(tmp_path / "plain.csv", _sine_rows())
    status = main(["fit", str(path), "--model", "bouc-wenn"])
    _check_line(capsys, status, "--model", ("invalid choice", "bouc-wen"))


def test_existing_json_is_kept_without_force(tmp_path, capsys):
    path = _csv(tmp_path / "plain.csv", _sine_rows())
    out = tmp_path / "fit.json"
    out.write_text("mine")
    status = main(["fit", str(path), *QUICK, "--json", str(out)])
    _check_line(capsys, status, "fit.json", ("--force",))
    assert out.read_text() == "mine"


def test_json_path_that_is_a_folder(tmp_path, capsys):
    path = _csv(tmp_path / "plain.csv", _sine_rows())
    status = main(["fit", str(path), *QUICK, "--json", str(tmp_path)])
    _check_line(capsys, status, "--json", ("folder",))


def test_simulate_out_that_is_a_file(tmp_path, capsys):
    out = tmp_path / "taken.csv"
    out.write_text("mine")
    status = main(["simulate", "--out", str(out)])
    _check_line(capsys, status, "taken.csv", ("not a folder",))
    assert out.read_text() == "mine"


def test_simulate_keeps_existing_outputs_without_force(tmp_path, capsys):
    (tmp_path / "simulation.csv").write_text("mine")
    status = main(["simulate", "--out", str(tmp_path)])
    _check_line(capsys, status, "simulation.csv", ("--force",))
    assert (tmp_path / "simulation.csv").read_text() == "mine"


def test_evaluate_without_a_model_file(tmp_path, capsys):
    path = _csv(tmp_path / "plain.csv", _sine_rows())
    status = main(["evaluate", str(tmp_path / "gone.json"), str(path)])
    _check_line(capsys, status, "gone.json", ("does not exist",))


# ------------------------------------------------ the fixes the messages suggest


def _read(argv: list[str]) -> list[Recording]:
    return load_recordings(build_parser(argv).parse_args(argv))


def test_suggested_no_time_reads_the_two_column_file(tmp_path):
    path = CASES["headerless-two-columns"].make(tmp_path)
    (recording,) = _read(["diagnose", "--model", "bouc-wen", "--no-time", str(path)])
    assert recording.num_samples == 40 and recording.time_unit == "sample"


def test_suggested_no_header_reads_the_three_column_file(tmp_path):
    path = CASES["headerless-three-columns"].make(tmp_path)
    (recording,) = _read(["fit", "--no-header", str(path)])
    np.testing.assert_allclose(recording.u, _sine_rows()[:, 1], rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize(
    ("data", "name"),
    [
        ("t,u [\xb5m],y\n0,0,0\n1,1,2\n2,0,1\n".encode("latin-1"), "latin-1"),
        (codecs.BOM_UTF8 + b"t,u,y\n0,0,0\n1,1,2\n2,0,1\n", "utf-8 with a mark"),
        (
            codecs.BOM_UTF16_LE + "t,u,y\n0,0,0\n1,1,2\n2,0,1\n".encode("utf-16-le"),
            "utf-16",
        ),
        (
            codecs.BOM_UTF16_BE + "t,u,y\n0,0,0\n1,1,2\n2,0,1\n".encode("utf-16-be"),
            "utf-16 big-endian",
        ),
    ],
)
def test_text_files_in_other_encodings_are_read(tmp_path, data, name):
    path = tmp_path / "encoded.csv"
    path.write_bytes(data)
    recording = Recording.load(path)
    np.testing.assert_array_equal(recording.y, [0, 2, 1])


def test_tiny_but_varying_input_is_not_called_constant():
    from jaxhyst._models.base import DataScales

    t = np.arange(40) * 0.01
    small = Recording(t, 1e-100 * np.sin(10 * t), np.sin(10 * t))
    rms = np.sqrt(np.mean(np.sin(10 * t) ** 2))
    assert DataScales.of(small).input_rms == pytest.approx(1e-100 * rms, rel=1e-12)
    huge = Recording(t, 1e140 * np.sin(10 * t), np.sin(10 * t))
    assert np.isfinite(DataScales.of(huge).input_rms)


# ------------------------------------------------------ Python words stay Python


def test_python_api_keeps_python_words(tmp_path):
    path = tmp_path / "raw.csv"
    path.write_text(_HEADERLESS)
    with pytest.raises(RecordingError, match="header=False") as raised:
        Recording.load(path)
    assert "--no-header" in cli_words(raised.value)
    assert "header=False" not in cli_words(raised.value)


@pytest.mark.parametrize(
    "message",
    [
        "identify: ExtendedDamper reads 2 inputs (displacement, command), recording "
        "'x' carries 1 (u); load it with every input (Recording.load(path, "
        "input=[...]), or --input repeated on the command line: --input u --input v).",
        "evaluate: ExtendedDamper reads 2 inputs (displacement, command), the input "
        "path carries 1; build it with InputPath(..., channels=...) or from a "
        "Recording with more inputs (Recording(..., more_inputs=...), --input "
        "repeated on the command line).",
        "diagnose: recording 'x' carries one input ('u'); the MR damper family reads "
        "the displacement and the command (voltage or current) beside it: load both, "
        "e.g. jaxhyst diagnose REC.csv --model mr-damper --input u --input v, "
        "Recording.load(path, input=['u', 'v']), or Recording(t, x, force, "
        "more_inputs={'command': v}); for a test at one fixed command, add it as a "
        "constant: rec.with_input('command', level).",
        "identify: recording 'b' is sampled at 1000 per s, 'a' at 200; recordings "
        "fitted together need one sample rate: resample them (Recording.resample).",
    ],
)
def test_python_fixes_of_other_modules_are_said_in_cli_words(message):
    said = cli_words(ValueError(message))
    assert not any(word in said for word in PYTHON_WORDS), said


def test_a_file_error_of_the_library_is_said_in_cli_words(tmp_path):
    with pytest.raises(FileNotFoundError, match="Recording.load") as raised:
        Recording.load(tmp_path / "gone.csv")
    said = cli_words(raised.value)
    assert "gone.csv" in said and not any(word in said for word in PYTHON_WORDS)


def test_a_window_of_one_sample_is_said_in_cli_words(tmp_path, capsys):
    path = _csv(tmp_path / "plain.csv", _sine_rows())
    status = main(["fit", str(path), *QUICK, "--start", "0.1", "--end", "0.101"])
    line = _check_line(capsys, status, "--start/--end", ("the window holds 1",))
    assert "segment(" not in line


def test_a_library_bug_keeps_its_traceback(tmp_path, monkeypatch):
    import jaxhyst._cli._options as options

    def broken(*args, **kwargs):
        return np.linalg.solve(np.zeros((2, 2)), np.ones(3))  # numpy's own ValueError

    monkeypatch.setattr(options, "load_recordings", broken)
    import jaxhyst._cli._fit as fit_command

    monkeypatch.setattr(fit_command, "load_recordings", broken)
    path = _csv(tmp_path / "plain.csv", _sine_rows())
    with pytest.raises(ValueError):
        main(["fit", str(path), *QUICK])


def test_battery_has_thirty_cases():
    assert len(CASES) + 6 >= 30
