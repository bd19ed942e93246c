"""Options and arguments shared by several commands: number parsers, the recording
options (columns, time window) and reading recordings, the swarm options, reading
a model file; and the one-line warnings every command prints."""

import argparse
import math
import sys
from pathlib import Path

from .._model_files import LoadedModel, load_model
from .._models.base import signal_scales
from .._recording import Recording, RecordingError
from .._swarm import MPSO
from ._choices import PRESETS
from ._words import SOURCES, in_file, one_line


PROG = "jaxhyst"


def warn(message: str) -> None:
    print(f"{PROG}: warning: {message}", file=sys.stderr)


# ------------------------------------------------------------------ numbers


def positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"{text} must be positive and finite")
    return value


def finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text} must be finite")
    return value


def positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text} must be at least 1")
    return value


# --------------------------------------------------------------- recordings


def add_recording_options(parser, *, several: bool = False) -> None:
    if several:
        parser.add_argument(
            "recording",
            metavar="RECORDING",
            nargs="+",
            help="the recording(s): .csv/.txt (columns picked by --time/--input/"
            "--output), .npz or .mat. Several recordings of one system (e.g. tests "
            "at several frequencies) are fitted with one model; the column and "
            "window options apply to each.",
        )
    else:
        parser.add_argument(
            "recording",
            metavar="RECORDING",
            help="the recording: .csv/.txt (columns picked by --time/--input/"
            "--output), .npz or .mat.",
        )
    group = parser.add_argument_group("columns of the recording")
    for option, default in (("time", "t"), ("input", "u"), ("output", "y")):
        index = ("t", "u", "y").index(default)
        no_time = "" if option == "time" else f", with --no-time: {index - 1}"
        repeat = (
            "; repeat it for a system with several inputs (an MR damper: --input u "
            "--input v; the first is the mechanical one). Without it, the inputs a "
            "jaxhyst-saved file names, else u"
            if option == "input"
            else ""
        )
        group.add_argument(
            f"--{option}",
            default=None,
            action="append" if option == "input" else "store",
            metavar="COLUMN",
            help=f"the {option} column: header name (default: {default}) or 0-based "
            f"index (default with --no-header: {index}{no_time}){repeat}"
            + (
                "; without it, the output a jaxhyst-saved file of several inputs "
                "names, else y"
                if option == "output"
                else ""
            )
            + ".",
        )
    group.add_argument(
        "--no-header",
        action="store_true",
        help="the text file has no header row; columns are picked by index.",
    )
    group.add_argument(
        "--no-time",
        action="store_true",
        help="the file has no time column: two columns (displacement, force), "
        "whitespace- or comma-separated, without a header; read with the pseudo "
        "time t = sample index (a quasi-static test; rate-independent models do not "
        "depend on it).",
    )
    window = parser.add_argument_group("time window")
    for option, compare, edge in (
        ("start", ">=", "from the beginning"),
        ("end", "<=", "to the end"),
    ):
        window.add_argument(
            f"--{option}",
            type=finite_float,
            default=None,
            metavar="T",
            help=f"analyse only the samples with t {compare} T (default: {edge} of "
            "the record), in the recording's time unit, keeping its time stamps; "
            "with --no-time, T is a sample index (the pseudo time).",
        )


def _quasi_static_column(text: str | None, index: int, option: str) -> int:
    if text is None:
        return index
    text = text.strip()
    if text not in ("0", "1"):
        raise ValueError(
            f"--{option} {text!r}: with --no-time the file has two columns, so pick "
            f"0 or 1 (default: --{option} {index})."
        )
    return int(text)


def column(text: str | None, default: str, index: int, header: bool, option: str):
    """The column `--option TEXT` picks: a header name or a 0-based index (`default`
    and `index` when not given)."""
    if text is None:
        return default if header else index
    text = text.strip()
    if text.isdigit():
        return int(text)
    if not header:
        raise ValueError(
            f"--{option} {text!r}: with --no-header pick columns by 0-based index, "
            f"e.g. --{option} {index}."
        )
    return text


def load_recordings(args: argparse.Namespace) -> list[Recording]:
    """Every recording named on the command line, each cut to --start/--end."""
    return [load_recording(args, path) for path in args.recording]


def load_recording(args: argparse.Namespace, path: str | None = None) -> Recording:
    """The recording named on the command line (or `path`), cut to
    --start/--end."""
    start, end = args.start, args.end
    if start is not None and end is not None and not start < end:
        raise ValueError(
            f"--start {start:g} --end {end:g}: the window is empty; pass --start "
            "below --end."
        )
    if path is None:
        path = str(args.recording)
    recording = _checked(_read_recording(args, path), path)
    SOURCES[recording.name] = path
    if start is None and end is None:
        return recording
    first, last = float(recording.t[0]), float(recording.t[-1])
    span = (
        f"the record {path!r} runs from t = {first:g} to {last:g} {recording.time_unit}"
    )
    if start is not None and start >= last:
        raise ValueError(
            f"--start {start:g} is at or past the end of the record ({span}); pick "
            f"--start below {last:g}."
        )
    if end is not None and end <= first:
        raise ValueError(
            f"--end {end:g} is at or before the start of the record ({span}); pick "
            f"--end above {first:g}."
        )
    try:
        part = recording.segment(start, end)
    except RecordingError as error:
        raise ValueError(f"--start/--end: {one_line(error.cli_message)}") from None
    return _checked(part, path, window=True)


def _checked(recording: Recording, path: str, *, window: bool = False) -> Recording:
    """`recording`, after checking that its input and output can be fitted or
    compared with a model: not constant, and of magnitudes a fit computes with
    (`signal_scales`). Errors name the file (and the window, `window`)."""
    span = "the window --start/--end" if window else "the whole record"
    for values, role in ((recording.u, "input"), (recording.y, "output")):
        try:
            signal_scales(values, role, span=span)
        except RecordingError as error:
            raise in_file(path, error) from None
    return recording


def window(args: argparse.Namespace, recording: Recording) -> dict[str, object]:
    """The "window" key of the JSON: --start/--end as given (None: not given)."""
    return {"start": args.start, "end": args.end, "time_unit": recording.time_unit}


def window_line(args: argparse.Namespace, recording: Recording) -> str | None:
    """The console line saying which part of the record is analysed."""
    if args.start is None and args.end is None:
        return None
    first, last = float(recording.t[0]), float(recording.t[-1])
    if recording.time_unit == "sample":
        where = f"samples {first:g} to {last:g}"
    else:
        unit = f" {recording.time_unit}" if recording.time_unit else ""
        where = f"t from {first:g} to {last:g}{unit}"
    given = ", ".join(
        f"--{name} {value:g}"
        for name, value in (("start", args.start), ("end", args.end))
        if value is not None
    )
    return f"window: {where} ({given}), {recording.num_samples} samples"


def _read_recording(args: argparse.Namespace, path: str) -> Recording:
    if not Path(path).is_file():
        what = "is a folder" if Path(path).is_dir() else "does not exist"
        raise FileNotFoundError(
            f"RECORDING {path!r} {what}; pass a recording file (.csv, .txt, .npz or "
            ".mat)."
        )
    if args.no_time:
        if args.time is not None:
            raise ValueError(
                f"--time {args.time} with --no-time: a file without a time column "
                "has none to pick; drop --time, or drop --no-time if the file has "
                "one."
            )
        if args.input is not None and len(args.input) > 1:
            raise ValueError(
                f"--input given {len(args.input)} times with --no-time: a file "
                "without a time column holds one input (displacement) and the output "
                "(force); pass --input once."
            )
        return Recording.load(
            path,
            time=None,
            input=_quasi_static_column(
                None if args.input is None else args.input[0], 0, "input"
            ),
            output=_quasi_static_column(args.output, 1, "output"),
            header=False,
        )
    header = not args.no_header
    if args.input is None:
        # A header: the inputs the file names (Recording.load's default).
        inputs = None if header else [column(None, "u", 1, header, "input")]
    else:
        inputs = [column(text, "u", 1, header, "input") for text in args.input]
    # With a header and no --output: the output the file names (a jaxhyst-saved
    # file of several inputs), else "y" (Recording.load's default).
    output = (
        None
        if header and args.output is None
        else column(args.output, "y", 2, header, "output")
    )
    return Recording.load(
        path,
        time=column(args.time, "t", 0, header, "time"),
        input=inputs,
        output=output,
        header=header,
    )


# -------------------------------------------------------------------- swarm


def add_swarm_options(parser, *, presets: bool) -> None:
    group = parser.add_argument_group("particle swarm")
    if presets:
        group.add_argument(
            "--preset",
            choices=tuple(PRESETS),
            default=None,
            help="the paper's MPSO settings of Table 3 (case1: 50 particles x 500 "
            "iterations, case2: 100 x 1500, case3: 300 x 5000, case4: 500 x 10000; "
            "c1=1.3, c2=1.7, w 0.9 to 0.1), searching the scaled unit box. Default: "
            "100 x 200, which finds the same basin in a fraction of the time. The "
            "swarm stops early once its best stalls for 40 iterations.",
        )
    group.add_argument(
        "--particles",
        type=positive_int,
        default=None,
        metavar="N",
        help="swarm size (for quick runs and tests; overrides --preset).",
    )
    group.add_argument(
        "--iterations",
        type=positive_int,
        default=None,
        metavar="N",
        help="swarm iterations (for quick runs and tests; overrides --preset).",
    )
    parser.add_argument(
        "--seed",
        type=int,
        default=0,
        help="random seed of the swarm (default: 0).",
    )


def diagnosis_swarm(args: argparse.Namespace) -> MPSO | None:
    """The base fit's swarm from --particles/--iterations, or None (the family's)."""
    if args.particles is None and args.iterations is None:
        return None
    return swarm(args)


def swarm(args: argparse.Namespace) -> MPSO:
    sizes = {}
    if args.particles is not None:
        if args.particles < 2:
            raise ValueError("--particles must be at least 2.")
        sizes["num_particles"] = args.particles
    if args.iterations is not None:
        sizes["num_iterations"] = args.iterations
    preset = getattr(args, "preset", None)
    if preset is not None:
        return MPSO.paper_case(PRESETS[preset], velocity_limit=0.2, **sizes)
    return MPSO(**{"num_particles": 100, "num_iterations": 200, **sizes})


# --------------------------------------------------------------- model file


def add_model_file_argument(parser) -> None:
    parser.add_argument(
        "model_file",
        metavar="MODEL",
        help="the model: a model file, or fit/diagnose JSON (its model_file block).",
    )


def load_model_file(path: str) -> LoadedModel:
    if not Path(path).is_file():
        what = "is a folder" if Path(path).is_dir() else "does not exist"
        raise FileNotFoundError(f"MODEL {path!r} {what}; pass a model file.")
    return load_model(path)
