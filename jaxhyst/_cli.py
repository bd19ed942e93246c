"""The `jaxhyst` command line.

Each subcommand is one pair of functions: `_add_<name>_parser(subparsers)` declares
its options and sets `run=_run_<name>`, and `_run_<name>(args) -> int` does the work.
`main` turns user errors (bad options, bad values, files in the way, unreadable
recordings, missing matplotlib) into one line `jaxhyst: error: ...` on stderr and
exit status 2, without a traceback; warnings go to stderr as `jaxhyst: warning: ...`.
"""

import argparse
import math
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NamedTuple, NoReturn

import jax
import numpy as np

from ._models.base import AbstractHysteresisModel
from ._models.bouc_wen import BoucWen, CorrectedPiezoBoucWen, PiezoBoucWen, PiezoStage
from ._plots import plot_loop, require_matplotlib
from ._recording import Recording, RecordingError
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


def _display_unit(unit: str) -> tuple[float, str]:
    """(scale, unit) to show a quantity stored in `unit`: metres as micrometres."""
    if unit == "m":
        return 1e6, "µm"
    if unit == "um":
        return 1.0, "µm"
    return 1.0, unit


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


# ------------------------------------------------------------------------- main


def _build_parser() -> _Parser:
    from . import __version__

    parser = _Parser(
        prog=_PROG,
        description=(
            "Bouc-Wen hysteresis models in JAX: simulate, identify, diagnose. "
            "Run 'jaxhyst COMMAND --help' for a command's options."
        ),
    )
    parser.add_argument(
        "--version", action="version", version=f"%(prog)s {__version__}"
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    _add_simulate_parser(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line with `argv` (default: `sys.argv[1:]`); returns the exit
    status: 0 on success, 2 on a user error (reported as one line on stderr)."""
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
