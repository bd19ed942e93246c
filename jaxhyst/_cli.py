"""The `jaxhyst` command line.

Each subcommand is one pair of functions: `_add_<name>_parser(subparsers)` declares
its options and sets `run=_run_<name>`, and `_run_<name>(args) -> int` does the work.
`main` turns user errors (bad options, bad values, files in the way, unreadable
recordings, missing matplotlib) into one line `jaxhyst: error: ...` on stderr and
exit status 2, without a traceback; warnings go to stderr as `jaxhyst: warning: ...`.
"""

import argparse
import dataclasses
import math
import os
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NamedTuple, NoReturn

import jax
import numpy as np

from ._cache import enable_compilation_cache
from ._compensate import compensate
from ._diagnose._diagnose import diagnose
from ._diagnose._families import (
    EFFECT_NAMES,
    AbstractFamily,
    PiezoFamily,
    StructuralFamily,
)
from ._diagnose._results import Diagnosis
from ._identification._corrected import CORRECTED_STAGES, identify_corrected
from ._identification._identify import identify
from ._metrics import error_metrics
from ._model_files import EMBEDDED_KEY, LoadedModel, load_model, model_file_dict
from ._models.base import AbstractHysteresisModel
from ._models.bouc_wen import BoucWen, CorrectedPiezoBoucWen, PiezoBoucWen, PiezoStage
from ._models.structural import StructuralBoucWen
from ._opensees import opensees_json
from ._plots import plot_loop, require_matplotlib
from ._recording import Recording, RecordingError
from ._report import (
    DIAGNOSIS_FIGURES,
    FIT_FIGURES,
    diagnosis_summary,
    display_unit as _display_unit,
    fit_summary,
    write_diagnosis_figures,
    write_diagnosis_report,
    write_fit_figures,
    write_json,
)
from ._signals import (
    AbstractSignal,
    Chirp,
    Multisine,
    Triangle,
    paper_u1,
    paper_u2,
    sample as sample_signal,
)
from ._simulate import RK4, simulate
from ._stability import bibo_stability
from ._status import RESULTS, status_name
from ._swarm import MPSO
from ._synthetic import demo_recording


_PROG = "jaxhyst"


class _UsageError(Exception):
    """A command line that argparse rejected: the message, and the (sub)command's
    prog for the `--help` hint."""

    def __init__(self, prog: str, message: str):
        super().__init__(message)
        self.prog = prog


class _Parser(argparse.ArgumentParser):
    """An ArgumentParser that raises instead of printing usage and exiting, so that
    `main` reports every error in the same one-line form."""

    def error(self, message: str) -> NoReturn:
        raise _UsageError(self.prog, message)


def _one_line(error: BaseException) -> str:
    text = " ".join(str(error).split())
    return text or type(error).__name__


def _warn(message: str) -> None:
    print(f"{_PROG}: warning: {message}", file=sys.stderr)


def _check_outputs(out: str | os.PathLike, names: Sequence[str], force: bool):
    """The output files `out/name`, after checking that `out` is (or can become) a
    folder and that none of them exists, unless `force`. Creates nothing."""
    folder = Path(out)
    if folder.exists() and not folder.is_dir():
        raise FileExistsError(
            f"--out {str(folder)!r} is a file, not a folder; pick another --out."
        )
    paths = [folder / name for name in names]
    if not force:
        existing = [repr(str(path)) for path in paths if path.exists()]
        if existing:
            verb = "exists" if len(existing) == 1 else "exist"
            raise FileExistsError(
                f"{' and '.join(existing)} already {verb}; pass --force to replace "
                "the outputs of an earlier run, or pick another --out."
            )
    return paths


# --------------------------------------------------------------------- simulate


class _ModelChoice(NamedTuple):
    description: str
    build: Callable[[], AbstractHysteresisModel]
    input_unit: str
    output_unit: str


def _model_choices() -> dict[str, _ModelChoice]:
    def paper() -> PiezoBoucWen:
        return PiezoBoucWen.paper_table4(3)

    return {
        "piezo": _ModelChoice(
            "PiezoBoucWen, the paper's Table 4 case 3 (eq. 7-8)", paper, "V", "m"
        ),
        "corrected": _ModelChoice(
            "CorrectedPiezoBoucWen, Table 4 case 3 with phi=0.05 s, eps=1e-6 "
            "(eq. 16-17)",
            lambda: CorrectedPiezoBoucWen.from_piezo(paper(), phi=0.05, eps=1e-6),
            "V",
            "m",
        ),
        "bouc-wen": _ModelChoice(
            "BoucWen (eq. 1-2), k=1, alpha=0.5, D=1, A=1, beta=0.6, gamma=0.4, n=1",
            lambda: BoucWen(k=1.0, alpha=0.5, D=1.0, A=1.0, beta=0.6, gamma=0.4, n=1.0),
            "",
            "",
        ),
        "stage": _ModelChoice(
            "PiezoStage (eq. 3-4), Table 4 case 3 with a 50 Hz, 0.1-damped stage",
            lambda: PiezoStage.from_piezo(
                paper(), natural_frequency=50.0, damping_ratio=0.1
            ),
            "V",
            "m",
        ),
    }


_SIGNALS = {
    "u1": "the paper's u1 = 2 - 2 cos(0.2 pi t), 0 to 4, 10 s per period",
    "u2": "the paper's u2 = 4 - 4 cos(0.2 pi t), 0 to 8, 10 s per period",
    "multisine": "random-phase multisine at 0.1, 0.3, 0.7, 1.3 Hz about 2, RMS 0.6",
    "chirp": "raised linear chirp 0 to 4 sweeping 0.1 to 2 Hz",
    "triangle": "raised triangle wave 0 to 4 at 0.1 Hz",
}


def _build_signal(name: str, periods: float, seed: int) -> AbstractSignal:
    duration = 10.0 * periods
    if name == "u1":
        return paper_u1(periods=periods)
    if name == "u2":
        return paper_u2(periods=periods)
    if name == "multisine":
        return Multisine.random_phase(
            jax.random.key(seed),
            np.array([0.1, 0.3, 0.7, 1.3]),
            rms=0.6,
            duration=duration,
            offset=2.0,
        )
    if name == "chirp":
        return Chirp(0.1, 2.0, 2.0, duration=duration)
    if name == "triangle":
        return Triangle(2.0, 0.1, duration=duration)
    raise ValueError(f"unknown signal {name!r}; choose from {', '.join(_SIGNALS)}.")


def _parse_params(items: Sequence[str], names: Sequence[str], model: str):
    """`NAME=VALUE` strings -> {name: float}, checked against the model's names."""
    valid = f"valid names for --model {model}: {', '.join(names)}"
    values: dict[str, float] = {}
    for item in items:
        name, sep, text = item.partition("=")
        name, text = name.strip(), text.strip()
        if not sep or not name:
            raise ValueError(f"--param {item!r}: expected NAME=VALUE; {valid}.")
        if name not in names:
            raise ValueError(f"--param {item}: unknown parameter {name!r}; {valid}.")
        try:
            value = float(text)
        except ValueError:
            raise ValueError(
                f"--param {item}: {text!r} is not a number; pass e.g. {name}=0.5 "
                f"({valid})."
            ) from None
        if not math.isfinite(value):
            raise ValueError(f"--param {item}: the value must be finite; {valid}.")
        values[name] = value
    return values


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"{text} must be positive and finite")
    return value


def _finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text} must be finite")
    return value


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text} must be at least 1")
    return value


def _add_simulate_parser(subparsers) -> None:
    choices = _model_choices()
    models = "; ".join(f"{k}: {v.description}" for k, v in choices.items())
    signals = "; ".join(f"{k}: {v}" for k, v in _SIGNALS.items())
    parser = subparsers.add_parser(
        "simulate",
        help="simulate a model under an excitation; write a CSV and a loop plot",
        description=(
            "Simulate a hysteresis model driven by an excitation signal and write "
            "OUT/simulation.csv (columns t, u, y, with units) and OUT/loop.png (the "
            "hysteresis loop y against u). Default: the paper's Table 4 case 3 piezo "
            "model under u1 sampled at 1000 Hz."
        ),
    )
    parser.add_argument(
        "--model",
        choices=tuple(choices),
        default="piezo",
        help=f"the model ({models}).",
    )
    parser.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override one model parameter, e.g. --param k2=0.3 (repeatable).",
    )
    parser.add_argument(
        "--signal",
        choices=tuple(_SIGNALS),
        default="u1",
        help=f"the excitation ({signals}).",
    )
    parser.add_argument(
        "--periods",
        type=_positive_float,
        default=1.0,
        help="length of the excitation in 10 s periods (default: 1).",
    )
    parser.add_argument(
        "--rate",
        type=_positive_float,
        default=1000.0,
        help="sample rate in Hz (default: 1000, as in the paper).",
    )
    parser.add_argument(
        "--substeps",
        type=_positive_int,
        default=1,
        help="RK4 steps per sample interval (default: 1); raise it for stiff models.",
    )
    parser.add_argument(
        "--seed",
        type=int,
        default=0,
        help="random seed of the multisine phases (default: 0).",
    )
    parser.add_argument(
        "--out",
        default="jaxhyst-out",
        metavar="DIR",
        help="output folder, created if missing (default: jaxhyst-out).",
    )
    parser.add_argument(
        "--force",
        action="store_true",
        help="replace simulation.csv and loop.png if they already exist in DIR.",
    )
    parser.set_defaults(run=_run_simulate)


def _run_simulate(args: argparse.Namespace) -> int:
    choice = _model_choices()[args.model]
    model = choice.build()
    overrides = _parse_params(args.param, model.parameter_names, args.model)
    if overrides:
        model = model.replace(**overrides)
    signal = _build_signal(args.signal, args.periods, args.seed)
    csv_path, png_path = _check_outputs(
        args.out, ("simulation.csv", "loop.png"), args.force
    )
    require_matplotlib()

    stability = bibo_stability(model)
    if not stability:
        _warn(
            f"parameters outside the BIBO-stable classes of Table 2 "
            f"({stability.reason}); the output may diverge."
        )
    path = sample_signal(signal, args.rate)
    y = np.asarray(simulate(model, path, RK4(substeps=args.substeps), throw=False))
    if not np.all(np.isfinite(y)):
        raise ValueError(
            "the simulation diverged (non-finite output); check the --param values "
            "against the stability classes, or raise --rate or --substeps."
        )
    recording = Recording(
        np.asarray(path.times),
        np.asarray(path.values),
        y,
        name=f"{args.model}-{args.signal}",
        input_unit=choice.input_unit,
        output_unit=choice.output_unit,
    )

    Path(args.out).mkdir(parents=True, exist_ok=True)
    recording.save(csv_path, overwrite=args.force)
    scale, y_unit = _display_unit(choice.output_unit)
    plot_loop(
        png_path,
        recording.u,
        {f"{type(model).__name__} ({args.model})": recording.y},
        xlabel="input u" + (f" [{choice.input_unit}]" if choice.input_unit else ""),
        ylabel="output y" + (f" [{y_unit}]" if y_unit else ""),
        title=f"{type(model).__name__} under {args.signal}: hysteresis loop",
        scale=scale,
        detrend=True,
        overwrite=args.force,
    )

    parameters = ", ".join(f"{k}={float(v):.6g}" for k, v in model.parameters().items())
    unit = f" {y_unit}" if y_unit else ""
    changed = f"; overridden: {', '.join(overrides)}" if overrides else ""
    print(f"model: {choice.description}{changed}")
    print(f"parameters: {parameters}")
    print(
        f"signal: {args.signal}, {recording.num_samples} samples at {args.rate:g} Hz "
        f"over {recording.duration:g} s"
    )
    print(
        f"output y: {scale * float(y.min()):.6g} to {scale * float(y.max()):.6g}{unit}"
    )
    print(f"wrote {csv_path}")
    print(f"wrote {png_path}")
    return 0


# ------------------------------------------------------ shared by fit / diagnose


_FIT_MODELS = {
    "piezo": "PiezoBoucWen (eq. 7-8)",
    "corrected": "CorrectedPiezoBoucWen (eq. 16-17), fitted in the paper's two "
    "stages: piezo, then (phi, eps) by the swarm, then all eight jointly",
    "bouc-wen": "BoucWen (eq. 1-2)",
    "stage": "PiezoStage (eq. 3-4, with mass and damping; RK4 with 4 substeps)",
}
_PRESETS = {f"case{case}": case for case in (1, 2, 3, 4)}


def _add_recording_options(parser, *, several: bool = False) -> None:
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
        group.add_argument(
            f"--{option}",
            default=None,
            metavar="COLUMN",
            help=f"the {option} column: header name (default: {default}) or 0-based "
            f"index (default with --no-header: {index}{no_time}).",
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
            type=_finite_float,
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


def _column(text: str | None, default: str, index: int, header: bool, option: str):
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


def _load_recordings(args: argparse.Namespace) -> list[Recording]:
    """Every recording named on the command line, each cut to --start/--end."""
    return [_load_recording(args, path) for path in args.recording]


def _load_recording(args: argparse.Namespace, path: str | None = None) -> Recording:
    """The recording named on the command line (or `path`), cut to
    --start/--end."""
    start, end = args.start, args.end
    if start is not None and end is not None and not start < end:
        raise ValueError(
            f"--start {start:g} --end {end:g}: the window is empty; pass --start "
            "below --end."
        )
    recording = _read_recording(args, args.recording if path is None else path)
    if start is None and end is None:
        return recording
    first, last = float(recording.t[0]), float(recording.t[-1])
    span = f"the record runs from t = {first:g} to {last:g} {recording.time_unit}"
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
        return recording.segment(start, end)
    except RecordingError as error:
        raise ValueError(f"--start/--end: {_one_line(error)}") from None


def _window(args: argparse.Namespace, recording: Recording) -> dict[str, object]:
    """The "window" key of the JSON: --start/--end as given (None: not given)."""
    return {"start": args.start, "end": args.end, "time_unit": recording.time_unit}


def _window_line(args: argparse.Namespace, recording: Recording) -> str | None:
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
    if args.no_time:
        if args.time is not None:
            raise ValueError(
                f"--time {args.time} with --no-time: a file without a time column "
                "has none to pick; drop --time, or drop --no-time if the file has "
                "one."
            )
        return Recording.load(
            path,
            time=None,
            input=_quasi_static_column(args.input, 0, "input"),
            output=_quasi_static_column(args.output, 1, "output"),
            header=False,
        )
    header = not args.no_header
    return Recording.load(
        path,
        time=_column(args.time, "t", 0, header, "time"),
        input=_column(args.input, "u", 1, header, "input"),
        output=_column(args.output, "y", 2, header, "output"),
        header=header,
    )


def _add_swarm_options(parser, *, presets: bool) -> None:
    group = parser.add_argument_group("particle swarm")
    if presets:
        group.add_argument(
            "--preset",
            choices=tuple(_PRESETS),
            default=None,
            help="the paper's MPSO settings of Table 3 (case1: 50 particles x 500 "
            "iterations, case2: 100 x 1500, case3: 300 x 5000, case4: 500 x 10000; "
            "c1=1.3, c2=1.7, w 0.9 to 0.1), searching the scaled unit box. Default: "
            "100 x 200, which finds the same basin in a fraction of the time. The "
            "swarm stops early once its best stalls for 40 iterations.",
        )
    group.add_argument(
        "--particles",
        type=_positive_int,
        default=None,
        metavar="N",
        help="swarm size (for quick runs and tests; overrides --preset).",
    )
    group.add_argument(
        "--iterations",
        type=_positive_int,
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


def _diagnosis_swarm(args: argparse.Namespace) -> MPSO | None:
    """The base fit's swarm from --particles/--iterations, or None (the family's)."""
    if args.particles is None and args.iterations is None:
        return None
    return _swarm(args)


def _swarm(args: argparse.Namespace) -> MPSO:
    sizes = {}
    if args.particles is not None:
        if args.particles < 2:
            raise ValueError("--particles must be at least 2.")
        sizes["num_particles"] = args.particles
    if args.iterations is not None:
        sizes["num_iterations"] = args.iterations
    preset = getattr(args, "preset", None)
    if preset is not None:
        return MPSO.paper_case(_PRESETS[preset], velocity_limit=0.2, **sizes)
    return MPSO(**{"num_particles": 100, "num_iterations": 200, **sizes})


def _check_files(paths: Sequence[tuple[str, Path]], force: bool) -> None:
    """Refuse output files (option, path) that are folders, or that exist unless
    `force`. Creates nothing."""
    for option, path in paths:
        if path.is_dir():
            raise FileExistsError(
                f"{option} {str(path)!r} is a folder, not a file; pick a file name."
            )
    if not force:
        existing = [repr(str(path)) for _, path in paths if path.exists()]
        if existing:
            verb = "exists" if len(existing) == 1 else "exist"
            raise FileExistsError(
                f"{' and '.join(existing)} already {verb}; pass --force to replace "
                "the outputs of an earlier run, or pick other output paths."
            )


def _check_folder(option: str, folder: Path, names: Sequence[str], force: bool):
    """The files `folder/name`, after checking `folder` is (or can become) a folder
    and none of them exists unless `force`. Creates nothing."""
    if folder.exists() and not folder.is_dir():
        raise FileExistsError(
            f"{option} {str(folder)!r} is a file, not a folder; pick another {option}."
        )
    paths = [(option, folder / name) for name in names]
    _check_files(paths, force)
    return [path for _, path in paths]


def _prepare_parent(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def _write_json(data, path: Path, force: bool) -> None:
    write_json(data, _prepare_parent(path), overwrite=force)
    print(f"wrote {path}")


def _print_written(paths) -> None:
    for path in paths:
        print(f"wrote {path}")


# -------------------------------------------------------------------------- fit


def _add_fit_parser(subparsers) -> None:
    models = "; ".join(f"{k}: {v}" for k, v in _FIT_MODELS.items())
    parser = subparsers.add_parser(
        "fit",
        help="identify a model from a recording (swarm + polish); summary, JSON, "
        "figures",
        description=(
            "Identify a hysteresis model from a recorded input/output pair: a particle "
            "swarm (MPSO) over a scaled parameter box, then a Levenberg-Marquardt "
            "polish on all samples. Prints the parameters (with standard errors), the "
            "error measures (RMSE, MAD, MRD, MAE, NRMSD) and the timing; --json and "
            "--plots save them. Several recordings are fitted with one model (the "
            "metrics then also per recording). Existing outputs are never replaced "
            "without --force."
        ),
    )
    _add_recording_options(parser, several=True)
    parser.add_argument(
        "--model",
        choices=tuple(_FIT_MODELS),
        default="piezo",
        help=f"the model to identify (default: piezo; {models}).",
    )
    _add_swarm_options(parser, presets=True)
    parser.add_argument(
        "--json",
        metavar="OUT",
        default=None,
        help="write the fit as JSON: model, parameters, metrics, identifiability, "
        "timing, swarm, polish.",
    )
    parser.add_argument(
        "--plots",
        metavar="DIR",
        default=None,
        help="write the paper-style figures into DIR (created if missing): "
        + ", ".join(FIT_FIGURES.values())
        + ".",
    )
    parser.add_argument(
        "--force",
        action="store_true",
        help="replace the JSON file and figures if they already exist.",
    )
    parser.set_defaults(run=_run_fit)


def _fit_template(name: str):
    if name == "bouc-wen":
        return BoucWen(k=1.0, alpha=0.5, D=1.0, A=1.0, beta=0.5, gamma=0.5, n=1.5)
    piezo = PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5)
    if name == "stage":
        return PiezoStage.from_piezo(piezo, natural_frequency=50.0, damping_ratio=0.5)
    return piezo


def _identify_corrected(recordings: list[Recording], key, swarm: MPSO):
    """`identify_corrected`, with its stages as the JSON's `stages` rows and the
    total time of all three."""
    joint, fits = identify_corrected(recordings, key=key, swarm=swarm, progress=True)
    stages = [
        {
            "stage": label,
            "model": type(fit.model).__name__,
            "rmse": fit.metrics["rmse"],
            "status": status_name(fit.result),
            "total_s": fit.timing["total_s"],
        }
        for label, fit in zip(CORRECTED_STAGES, fits)
    ]
    timing = dict(joint.timing)
    timing["total_s"] = sum(stage["total_s"] for stage in stages)
    return dataclasses.replace(joint, timing=timing), stages


def _recording_json(recording: Recording) -> dict[str, object]:
    return {
        "name": recording.name,
        "samples": recording.num_samples,
        "sample_rate_hz": recording.sample_rate,
        "input_unit": recording.input_unit,
        "output_unit": recording.output_unit,
    }


def _plot_folders(plots: Path, recordings: list[Recording]) -> list[Path]:
    """Where each recording's figures go: DIR itself for one recording, else one
    subfolder per recording (named after it, numbered when names repeat)."""
    if len(recordings) == 1:
        return [plots]
    names = [r.name for r in recordings]
    return [
        plots / (name if names.count(name) == 1 else f"{i + 1}_{name}")
        for i, name in enumerate(names)
    ]


def _run_fit(args: argparse.Namespace) -> int:
    swarm = _swarm(args)
    outputs: list[tuple[str, Path]] = []
    json_path = Path(args.json) if args.json is not None else None
    if json_path is not None:
        outputs.append(("--json", json_path))
    _check_files(outputs, args.force)
    recordings = _load_recordings(args)
    plots = Path(args.plots) if args.plots is not None else None
    folders = [] if plots is None else _plot_folders(plots, recordings)
    for folder in folders:
        _check_folder("--plots", folder, tuple(FIT_FIGURES.values()), args.force)
    if folders:
        require_matplotlib()

    key = jax.random.key(args.seed)
    stages = None
    if args.model == "corrected":
        fit, stages = _identify_corrected(recordings, key, swarm)
    else:
        if args.model == "stage":
            solver = RK4(substeps=4)
        elif args.model == "bouc-wen":
            solver = StructuralFamily().solver(recordings[0])
        else:
            solver = RK4()
        fit = identify(
            _fit_template(args.model),
            recordings,
            key=key,
            swarm=swarm,
            solver=solver,
            progress=True,
            throw=False,
        )
    if fit.result == RESULTS.nonfinite:
        raise ValueError(
            "the fitted model's output is not finite; try another --seed, a larger "
            "swarm, or check the recording."
        )
    for recording in recordings:
        print(
            f"recording: {recording.name}, {recording.num_samples} samples at "
            f"{recording.sample_rate:g} Hz over {recording.duration:g} s"
        )
        window = _window_line(args, recording)
        if window is not None:
            print(window)
    print(fit_summary(fit, recordings[0]))
    if stages is not None:
        print("stages:")
        for stage in stages:
            print(
                f"  {stage['stage']}: RMSE {stage['rmse']:.6g}, "
                f"{stage['total_s']:.1f} s"
            )
    if json_path is not None:
        data = fit.to_dict()
        if len(recordings) == 1:
            data["recording"] = _recording_json(recordings[0])
        data["recordings"] = [_recording_json(r) for r in recordings]
        data["command"] = {"model": args.model, "seed": args.seed}
        data["window"] = _window(args, recordings[0])
        if isinstance(fit.model, BoucWen):
            data.update(opensees_json(fit.model, recordings[0]))
        if stages is not None:
            data["stages"] = stages
        # The model file (jh.load_model and 'jaxhyst evaluate' read it from here).
        data[EMBEDDED_KEY] = model_file_dict(fit.model, recording=recordings)
        _write_json(data, json_path, args.force)
    for i, (recording, folder) in enumerate(zip(recordings, folders)):
        written = write_fit_figures(
            fit.for_recording(i),
            recording,
            folder,
            overwrite=args.force,
            label=args.model,
        )
        _print_written(written.values())
    return 0


# --------------------------------------------------------------------- diagnose


def _add_diagnose_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "diagnose",
        help="find the physics a piezo model leaves out of a recording; summary, "
        "JSON, figures, Markdown report",
        description=(
            "Fit the quasi-static piezo model (eq. 7-8) on part of a recording, score "
            "every catalogue effect (" + ", ".join(EFFECT_NAMES) + ") on its residual, "
            "refit the strongest, and keep an effect only if it lowers the error on "
            "held-out data by more than the noise; repeat. Prints the findings with "
            "their evidence, the RMSE before/after and any ambiguities; --json, "
            "--plots and --report save them. Existing outputs are never replaced "
            "without --force."
        ),
    )
    _add_recording_options(parser)
    parser.add_argument(
        "--model",
        default="piezo",
        metavar="NAME",
        help="the family: 'piezo' (default; PiezoBoucWen with asymmetry, input "
        "bias, rate dependence, creep, dynamics, drift) or 'bouc-wen' (structural "
        "cyclic tests, columns t,u,y = pseudo time, displacement, force: BoucWen with "
        "degradation, pinching, asymmetry, drift; the JSON then carries the matching "
        "OpenSees material under 'opensees').",
    )
    _add_swarm_options(parser, presets=False)
    parser.add_argument(
        "--json",
        metavar="PATH",
        default=None,
        help="write the diagnosis as JSON (schema in the README).",
    )
    parser.add_argument(
        "--plots",
        metavar="DIR",
        default=None,
        help="write the figures into DIR (created if missing): "
        + ", ".join(DIAGNOSIS_FIGURES.values())
        + ".",
    )
    parser.add_argument(
        "--report",
        metavar="PATH",
        default=None,
        help="write a Markdown report linking the figures (into --plots, or else a "
        "folder PATH-stem_figures next to the report).",
    )
    parser.add_argument(
        "--force",
        action="store_true",
        help="replace the JSON file, figures and report if they already exist.",
    )
    parser.set_defaults(run=_run_diagnose)


# The one table from --model names to diagnosis families.
_DIAGNOSE_FAMILIES: dict[str, Callable[[], AbstractFamily]] = {
    "piezo": PiezoFamily,
    "bouc-wen": StructuralFamily,
}


def _family(name: str) -> AbstractFamily:
    if name not in _DIAGNOSE_FAMILIES:
        known = (
            f"{name!r} is a model 'jaxhyst fit' can identify, but diagnose has no "
            "effect catalogue for it"
            if name in _FIT_MODELS
            else f"unknown model {name!r}"
        )
        raise ValueError(
            f"--model {name}: {known}; use --model piezo (piezo actuators and stages) "
            "or --model bouc-wen (structural cyclic tests: displacement -> force)."
        )
    return _DIAGNOSE_FAMILIES[name]()


def _run_diagnose(args: argparse.Namespace) -> int:
    family = _family(args.model)
    swarm = _diagnosis_swarm(args)
    files: list[tuple[str, Path]] = []
    json_path = Path(args.json) if args.json is not None else None
    report_path = Path(args.report) if args.report is not None else None
    if json_path is not None:
        files.append(("--json", json_path))
    if report_path is not None:
        files.append(("--report", report_path))
    _check_files(files, args.force)
    plots = Path(args.plots) if args.plots is not None else None
    if plots is None and report_path is not None:
        plots = report_path.parent / f"{report_path.stem}_figures"
    if plots is not None:
        _check_folder("--plots", plots, tuple(DIAGNOSIS_FIGURES.values()), args.force)
        require_matplotlib()
    recording = _load_recording(args)

    diagnosis = diagnose(
        recording,
        key=jax.random.key(args.seed),
        family=family,
        swarm=swarm,
        progress=True,
    )
    window = _window_line(args, recording)
    if window is not None:
        print(window)
    print(diagnosis_summary(diagnosis, recording))
    if json_path is not None:
        data = diagnosis.to_dict()
        data["window"] = _window(args, recording)
        data[EMBEDDED_KEY] = _diagnosis_model_file(diagnosis, recording)
        _write_json(data, json_path, args.force)
    figures = {}
    if plots is not None:
        figures = write_diagnosis_figures(
            diagnosis, recording, plots, overwrite=args.force
        )
        _print_written(figures.values())
    if report_path is not None:
        extra = {"diagnosis JSON": json_path} if json_path is not None else None
        write_diagnosis_report(
            diagnosis,
            recording,
            _prepare_parent(report_path),
            figures,
            overwrite=args.force,
            files=extra,
        )
        print(f"wrote {report_path}")
    return 0


def _diagnosis_model_file(
    diagnosis: Diagnosis, recording: Recording
) -> dict[str, object]:
    """The model file of the final (diagnosed) model, embedded in the JSON."""
    return model_file_dict(
        diagnosis.final_model,
        recording=recording,
        family=diagnosis.family,
        effects=diagnosis.effects,
    )


# --------------------------------------------------------------------- evaluate


def _add_evaluate_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "evaluate",
        help="simulate a saved model on recordings and report its errors",
        description=(
            "Simulate a saved model (a model file from jh.save_model, or the JSON of "
            "'jaxhyst fit --json' or 'jaxhyst diagnose --json') on each recording's "
            "input and report the error measures (RMSE, MAD, MRD, MAE, NRMSD) "
            "against its output: how a model does on tests it was not fitted to. "
            "The solver is the one 'jaxhyst fit' uses for the model: RK4 with 4 "
            "substeps for PiezoStage, the structural family's substeps for BoucWen "
            "and StructuralBoucWen, else one RK4 step per sample."
        ),
    )
    parser.add_argument(
        "model_file",
        metavar="MODEL",
        help="the model: a model file, or fit/diagnose JSON (its model_file block).",
    )
    _add_recording_options(parser, several=True)
    parser.add_argument(
        "--json",
        metavar="OUT",
        default=None,
        help='write {"recordings": [{"recording": path, "metrics": {rmse, mad, mrd, '
        "mae, nrmsd}}, ...]} as JSON.",
    )
    parser.add_argument(
        "--force",
        action="store_true",
        help="replace the JSON file if it already exists.",
    )
    parser.set_defaults(run=_run_evaluate)


def _evaluation_solver(model: AbstractHysteresisModel, recording: Recording) -> RK4:
    """The solver `jaxhyst fit` / `diagnose` simulate this kind of model with."""
    if isinstance(model, PiezoStage):
        return RK4(substeps=4)
    if isinstance(model, (BoucWen, StructuralBoucWen)):
        return StructuralFamily().solver(recording)
    return RK4()


def _check_units(loaded: LoadedModel, recording: Recording, path: str) -> None:
    """Refuse a recording whose declared input/output units differ from the
    model's (where both declare one): the errors would be off by the conversion."""
    for key in ("input", "output"):
        ours, theirs = loaded.units[key], getattr(recording, f"{key}_unit")
        if ours and theirs and ours != theirs:
            raise ValueError(
                f"{path}: its {key} is in {theirs}, the model's in {ours}; convert "
                "the recording to the model's units."
            )


def _load_model_file(path: str) -> LoadedModel:
    if not Path(path).is_file():
        what = "is a folder" if Path(path).is_dir() else "does not exist"
        raise FileNotFoundError(f"MODEL {path!r} {what}; pass a model file.")
    return load_model(path)


def _run_evaluate(args: argparse.Namespace) -> int:
    json_path = Path(args.json) if args.json is not None else None
    if json_path is not None:
        _check_files([("--json", json_path)], args.force)
    loaded = _load_model_file(args.model_file)
    model = loaded.model
    recordings = _load_recordings(args)
    for path, recording in zip(args.recording, recordings):
        _check_units(loaded, recording, path)

    results = []
    for path, recording in zip(args.recording, recordings):
        solver = _evaluation_solver(model, recording)
        y = np.asarray(simulate(model, recording.input_path(), solver, throw=False))
        if not np.all(np.isfinite(y)):
            raise ValueError(
                f"the model's output on {path} is not finite (it diverged); check "
                "that the recording's input is in the model's units and range."
            )
        results.append((path, recording, error_metrics(recording.y, y)))

    fitted = ", ".join(
        f"{r.get('name')} ({r.get('samples')} samples)" for r in loaded.recordings
    )
    effects = f" + {', '.join(loaded.effects)}" if loaded.effects else ""
    print(
        f"model: {type(model).__name__}{effects} from {args.model_file} (jaxhyst "
        f"{loaded.jaxhyst_version}" + (f"; fitted to {fitted})" if fitted else ")")
    )
    scale, unit = _display_unit(loaded.units["output"] or recordings[0].output_unit)
    s = f" [{unit}]" if unit else ""
    width = max(len("recording"), *(len(path) for path in args.recording))
    print(
        f"{'recording':<{width}}  {'samples':>8}  {'RMSE' + s:>13}  {'MAD' + s:>13}  "
        f"{'MRD [%]':>11}  {'MAE' + s:>13}  {'NRMSD':>11}"
    )
    for path, recording, m in results:
        print(
            f"{path:<{width}}  {recording.num_samples:>8}  "
            f"{scale * m['rmse']:>13.6g}  {scale * m['mad']:>13.6g}  "
            f"{m['mrd']:>11.6g}  {scale * m['mae']:>13.6g}  {m['nrmsd']:>11.6g}"
        )
        window = _window_line(args, recording)
        if window is not None:
            print(f"  {window}")
    if json_path is not None:
        data = {
            "model": {"file": args.model_file, "class": type(model).__name__},
            "recordings": [
                {
                    "recording": path,
                    "name": recording.name,
                    "samples": recording.num_samples,
                    "metrics": metrics,
                }
                for path, recording, metrics in results
            ],
            "window": _window(args, recordings[0]),
        }
        _write_json(data, json_path, args.force)
    return 0


# ------------------------------------------------------------------------- demo


_DEMO_FIGURES = {
    **{name: f"figures/{file}" for name, file in FIT_FIGURES.items()},
    **{name: f"figures/{file}" for name, file in DIAGNOSIS_FIGURES.items()},
}
_DEMO_FILES = ("recording.csv", "fit.json", "diagnosis.json", "report.md")


def _add_demo_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "demo",
        help="identify and diagnose the bundled demo recording; write a report",
        description=(
            "The whole pipeline on the bundled demo recording (a paper-like piezo "
            "stage under u2 scaled to 0-100 V, 30 s at 1 kHz, concealing two effects "
            "under sensor noise): fit the plain piezo model (swarm + polish), "
            "diagnose the missing physics and refit, and write DIR/report.md with "
            "the paper-style figures (DIR/figures/), a before/after table in the "
            "format of the paper's Tables 5/6, the findings with their evidence, "
            "and DIR/recording.csv, DIR/fit.json, DIR/diagnosis.json. Takes about two "
            "minutes on two CPU cores, most of it in the diagnosis's refits."
        ),
    )
    parser.add_argument(
        "--out",
        default="jaxhyst-demo",
        metavar="DIR",
        help="output folder, created if missing (default: jaxhyst-demo).",
    )
    parser.add_argument(
        "--seed",
        type=int,
        default=0,
        help="random seed of the swarms (default: 0); the recording is always the "
        "bundled one.",
    )
    parser.add_argument(
        "--force",
        action="store_true",
        help="replace the outputs of an earlier run in DIR.",
    )
    parser.set_defaults(run=_run_demo)


def _run_demo(args: argparse.Namespace) -> int:
    out = Path(args.out)
    names = (*_DEMO_FILES, *_DEMO_FIGURES.values())
    _check_outputs(out, names, args.force)
    require_matplotlib()
    start = time.perf_counter()
    key = jax.random.key(args.seed)

    case = demo_recording()
    recording = case.recording
    scale, unit = _display_unit(recording.output_unit)
    print(
        f"demo recording {recording.name!r}: {recording.num_samples} samples at "
        f"{recording.sample_rate:g} Hz over {recording.duration:g} s; u in "
        f"{recording.input_unit}, y in {unit}"
    )
    print(
        "step 1/2: fit the plain piezo model on all samples (swarm + polish; the "
        "figures of the plain model, not the diagnosis's base)",
        flush=True,
    )
    fit = identify(
        PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5),
        recording,
        key=jax.random.fold_in(key, 0),
        progress=True,
    )
    print(fit_summary(fit, recording))
    print(
        "step 2/2: diagnose the missing physics (base fit, score, refit, "
        "validate on held-out data)",
        flush=True,
    )
    diagnosis = diagnose(recording, key=jax.random.fold_in(key, 1), progress=True)
    print(diagnosis_summary(diagnosis, recording))

    out.mkdir(parents=True, exist_ok=True)
    (out / "figures").mkdir(exist_ok=True)
    recording.save(out / "recording.csv", overwrite=args.force)
    fit_data = fit.to_dict()
    fit_data["recording"] = {"name": recording.name, "samples": recording.num_samples}
    fit_data[EMBEDDED_KEY] = model_file_dict(fit.model, recording=recording)
    write_json(fit_data, out / "fit.json", overwrite=args.force)
    diagnosis_data = diagnosis.to_dict()
    diagnosis_data[EMBEDDED_KEY] = _diagnosis_model_file(diagnosis, recording)
    write_json(diagnosis_data, out / "diagnosis.json", overwrite=args.force)
    figures = {
        **write_fit_figures(
            fit, recording, out / "figures", overwrite=args.force, label="piezo"
        ),
        **write_diagnosis_figures(
            diagnosis, recording, out / "figures", overwrite=args.force
        ),
    }
    concealed = " and ".join(
        f"{effect} ({case.sizes[effect]:.2g} σ)" for effect in case.effects
    )
    named, truth = diagnosis.effects, set(case.effects)
    found = [e for e in named if e in truth]
    missed = sorted(truth - set(named))
    extra = [e for e in named if e not in truth]

    def listed(names):
        names = list(names)
        return " and ".join([", ".join(names[:-1]), names[-1]] if names[1:] else names)

    if not named:
        verdict = f"It named nothing, so it missed {listed(sorted(truth))}."
    else:
        verdict = f"It named {listed(named)}: of the concealed effects it found "
        verdict += listed(found) if found else "none"
        verdict += f" and missed {listed(missed)}" if missed else " and missed none"
        verdict += f"; {listed(extra)} is extra" if extra else ""
        verdict += " (see the findings and the ambiguities)."
    intro = (
        "The bundled demo (`jaxhyst demo`): a synthetic paper-like piezo stage under "
        "the paper's u2 = 4 - 4 cos(0.2 π t), scaled to 0-100 V, 30 s at 1 kHz. The "
        f"recording conceals {concealed} under white sensor noise of σ = "
        f"{scale * case.sigma:.3g} {unit}; each effect alone changes the output by "
        "only that many noise sigmas (RMS), so the loop looks ordinary to the eye. "
        f"The diagnosis is not told what is concealed. {verdict}\n\n"
        "Figures 8-10 show the plain piezo model fitted to the whole record (the "
        "layout of the paper's Figures 8-10: loop, time histories, absolute error); "
        "Figures 11-13 the same before/after the diagnosis (as the paper's Figures "
        "11-13 for its corrected model); Figures 14-17 the residual analysis."
    )
    report = write_diagnosis_report(
        diagnosis,
        recording,
        out / "report.md",
        figures,
        overwrite=args.force,
        fit=fit,
        files={
            "recording (CSV)": out / "recording.csv",
            "plain piezo fit (JSON)": out / "fit.json",
            "diagnosis (JSON)": out / "diagnosis.json",
        },
        first_figure=8,
        title="jaxhyst demo: identify a piezo model, diagnose what it leaves out",
        intro=intro,
    )
    print(f"wrote {len(figures)} figures to {out / 'figures'}")
    print(
        f"wrote {out / 'recording.csv'}, {out / 'fit.json'}, {out / 'diagnosis.json'}"
    )
    print(f"demo finished in {time.perf_counter() - start:.0f} s")
    print(f"report: {report}")
    return 0


# ------------------------------------------------------------------------- main


# ------------------------------------------------------------------- compensate

_COMPENSATION_FIGURES = ("compensation_drive.png", "compensation_error.png")


def _add_compensate_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "compensate",
        help="the drive that makes a saved model follow a reference (feedforward)",
        description=(
            "Find the drive u(t) whose simulated output follows a reference y(t) "
            "for a saved piezo model: a causal per-sample inversion where the "
            "model allows it (PiezoBoucWen, CorrectedPiezoBoucWen, a diagnosed "
            "ExtendedPiezo), else, for models whose output lags the drive (stage "
            "dynamics, a time shift), the whole drive optimised through the "
            "simulator ahead of time. Writes DRIVE.csv with columns t,u,y_predicted "
            "on the reference's time grid. Samples the model cannot reach inside "
            "--limits are reported, never silently clipped."
        ),
    )
    parser.add_argument(
        "model_file",
        metavar="MODEL",
        help="the model: a model file, or fit/diagnose JSON (its model_file block).",
    )
    parser.add_argument(
        "reference",
        metavar="REFERENCE",
        help="the reference: .csv/.txt with a header and columns t,y (in the units "
        "of the recording the model was fitted on), or .npz/.mat.",
    )
    group = parser.add_argument_group("columns of the reference")
    group.add_argument(
        "--time",
        default=None,
        metavar="COLUMN",
        help="the time column (default: t; with --no-header: 0).",
    )
    group.add_argument(
        "--output",
        default=None,
        metavar="COLUMN",
        help="the reference column (default: y; with --no-header: 1).",
    )
    group.add_argument(
        "--no-header",
        action="store_true",
        help="the text file has no header row (columns by index).",
    )
    parser.add_argument(
        "--out",
        required=True,
        metavar="DRIVE",
        help="write the drive here (.csv: t,u,y_predicted).",
    )
    parser.add_argument(
        "--limits",
        default=None,
        metavar="LO,HI",
        help="the drive's range, e.g. 0,150 for a 0-150 V amplifier (default: the "
        "input range of the recordings the model was fitted on, as the model file "
        "records it: beyond it the model extrapolates).",
    )
    parser.add_argument(
        "--report",
        default=None,
        metavar="PATH",
        help="write a Markdown report (tracking error, figures "
        "next to it: " + ", ".join(_COMPENSATION_FIGURES) + ").",
    )
    parser.add_argument(
        "--force", action="store_true", help="replace existing outputs."
    )
    parser.set_defaults(run=_run_compensate)


def _limits(args: argparse.Namespace, loaded: LoadedModel) -> tuple[float, float]:
    if args.limits is not None:
        parts = args.limits.split(",")
        try:
            lo, hi = (float(p) for p in parts)
        except ValueError:
            raise ValueError(
                f"--limits {args.limits!r}: give two numbers LO,HI, e.g. --limits 0,150."
            ) from None
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ValueError(
                f"--limits {args.limits!r}: need finite LO < HI, e.g. --limits 0,150."
            )
        return lo, hi
    ranges = [r.get("input_range") for r in loaded.recordings]
    known = [(float(r[0]), float(r[1])) for r in ranges if r is not None]
    if not known or len(known) < len(ranges):
        raise ValueError(
            f"{args.model_file} does not record the input range it was fitted on; "
            "pass the drive's range with --limits LO,HI (e.g. --limits 0,150)."
        )
    return min(lo for lo, _ in known), max(hi for _, hi in known)


def _read_reference(args: argparse.Namespace) -> Recording:
    header = not args.no_header
    column = _column(args.output, "y", 1, header, "output")
    return Recording.load(
        args.reference,
        time=_column(args.time, "t", 0, header, "time"),
        input=column,
        output=column,
        header=header,
    )


def _run_compensate(args: argparse.Namespace) -> int:
    out = Path(args.out)
    report = Path(args.report) if args.report is not None else None
    outputs = [("--out", out)]
    if report is not None:
        outputs.append(("--report", report))
        outputs += [
            ("--report", report.parent / name) for name in _COMPENSATION_FIGURES
        ]
    _check_files(outputs, args.force)
    if report is not None:
        require_matplotlib()
    loaded = _load_model_file(args.model_file)
    reference = _read_reference(args)
    limits = _limits(args, loaded)
    result = compensate(
        loaded.model,
        reference.t,
        reference.y,
        limits=limits,
        solver=_evaluation_solver(loaded.model, reference),
        throw=False,
    )
    if result.result == RESULTS.nonfinite:
        raise ValueError(
            "the model diverged while following the reference; check that the "
            "reference is in the model's output units and inside its stroke."
        )
    tracking = result.tracking()
    scale, unit = _display_unit(loaded.units["output"] or reference.output_unit)
    s = f" {unit}" if unit else ""
    print(
        f"model: {type(loaded.model).__name__} from {args.model_file}; reference "
        f"{reference.name}: {reference.num_samples} samples at "
        f"{reference.sample_rate:g} Hz; drive limits {limits[0]:g} to {limits[1]:g}; "
        f"method: {result.method}"
    )
    print(
        f"predicted tracking error: RMS {scale * tracking['rms_error']:.4g}{s} "
        f"({tracking['rms_error_percent_of_stroke']:.3g} % of the stroke), max "
        f"{scale * tracking['max_error']:.4g}{s} "
        f"({tracking['max_error_percent_of_stroke']:.3g} %)"
    )
    if tracking["samples_at_limit"]:
        _warn(
            f"{tracking['samples_at_limit']} of {reference.num_samples} samples need "
            f"a drive outside {limits[0]:g} to {limits[1]:g}: the model cannot reach "
            "the reference there (the drive is held at the limit); widen --limits "
            "if the amplifier allows."
        )
    _prepare_parent(out)
    table = np.stack(
        [
            np.asarray(result.times),
            np.asarray(result.drive),
            np.asarray(result.predicted),
        ],
        axis=1,
    )
    np.savetxt(
        out, table, delimiter=",", header="t,u,y_predicted", comments="", fmt="%.17g"
    )
    written = [out]
    if report is not None:
        written += _write_compensation_report(
            report, args, loaded, reference, result, limits, scale, unit
        )
    _print_written(written)
    return 0


def _write_compensation_report(
    report, args, loaded, reference, result, limits, scale, unit
) -> list[Path]:
    from ._plots import plot_error_trend, plot_time_history

    _prepare_parent(report)
    folder = report.parent
    t = np.asarray(result.times)
    label = f"output [{unit}]" if unit else "output"
    drive = plot_time_history(
        folder / _COMPENSATION_FIGURES[0],
        t,
        np.asarray(result.drive),
        {"reference": reference.y, "predicted": np.asarray(result.predicted)},
        ulabel="drive u",
        ylabel=label,
        scale=scale,
        overwrite=args.force,
        title="Compensation: drive (top), reference and predicted output",
    )
    error = plot_error_trend(
        folder / _COMPENSATION_FIGURES[1],
        t,
        {"|predicted - reference|": np.abs(np.asarray(result.error))},
        ylabel=f"absolute error [{unit}]" if unit else "absolute error",
        scale=scale,
        overwrite=args.force,
        title="Predicted tracking error",
    )
    tracking = result.tracking()
    s = f" {unit}" if unit else ""
    lines = [
        "# Compensation",
        "",
        f"Model `{type(loaded.model).__name__}` from `{args.model_file}`; reference "
        f"`{args.reference}` ({reference.num_samples} samples at "
        f"{reference.sample_rate:g} Hz); drive limits {limits[0]:g} to {limits[1]:g}.",
        "",
        f"Method: {result.method} ("
        + (
            "at every sample, the drive in the limits whose one-sample simulation "
            "meets the reference, by bisection"
            if result.method == "per-sample inversion"
            else "the whole drive optimised through the simulator, from the inverse "
            "of the model's quasi-static part"
        )
        + "). The errors are the model's prediction: the stage tracks as well as "
        "the model describes it.",
        "",
        "| predicted tracking error | value | % of stroke |",
        "|---|---|---|",
        f"| RMS | {scale * tracking['rms_error']:.4g}{s} | "
        f"{tracking['rms_error_percent_of_stroke']:.3g} |",
        f"| maximum | {scale * tracking['max_error']:.4g}{s} | "
        f"{tracking['max_error_percent_of_stroke']:.3g} |",
        "",
        f"Samples out of reach inside the limits: {tracking['samples_at_limit']}.",
        "",
        f"![drive and output]({drive.name})",
        "",
        f"![tracking error]({error.name})",
        "",
    ]
    report.write_text("\n".join(lines))
    return [report, drive, error]


def _build_parser() -> _Parser:
    from . import __version__

    parser = _Parser(
        prog=_PROG,
        description=(
            "Bouc-Wen hysteresis models in JAX: simulate, identify, diagnose. "
            "Run 'jaxhyst COMMAND --help' for a command's options. Compiled "
            "programs are cached on disk so that later runs start faster "
            "(JAXHYST_CACHE_DIR moves the cache; an empty value turns it off)."
        ),
    )
    parser.add_argument(
        "--version", action="version", version=f"%(prog)s {__version__}"
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    _add_simulate_parser(subparsers)
    _add_fit_parser(subparsers)
    _add_diagnose_parser(subparsers)
    _add_evaluate_parser(subparsers)
    _add_compensate_parser(subparsers)
    _add_demo_parser(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line with `argv` (default: `sys.argv[1:]`); returns the exit
    status: 0 on success, 2 on a user error (reported as one line on stderr)."""
    enable_compilation_cache()
    jax.config.update("jax_enable_x64", True)
    parser = _build_parser()
    try:
        args = parser.parse_args(argv)
        return args.run(args)
    except _UsageError as error:
        print(
            f"{_PROG}: error: {_one_line(error)} (see '{error.prog} --help')",
            file=sys.stderr,
        )
        return 2
    except SystemExit as stop:  # --help and --version
        return stop.code if isinstance(stop.code, int) else 0
    except (RecordingError, ValueError, TypeError, ImportError, OSError) as error:
        print(f"{_PROG}: error: {_one_line(error)}", file=sys.stderr)
        return 2
