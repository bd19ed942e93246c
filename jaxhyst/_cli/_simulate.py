"""`jaxhyst simulate`: a model under an excitation; a CSV and a loop plot."""

import argparse
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .._plots import require_matplotlib, save_figure
from .._recording import Recording
from .._report import display_unit, loop_figure
from .._signals import sample
from .._simulate import RK4, simulate
from .._stability import bibo_stability
from ._choices import SIGNALS, SIMULATE_MODELS, described
from ._options import positive_float, positive_int, warn
from ._outputs import check_folder


def add_parser(subparsers) -> None:
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
        choices=tuple(SIMULATE_MODELS),
        default="piezo",
        help=f"the model ({described(SIMULATE_MODELS)}).",
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
        choices=tuple(SIGNALS),
        default="u1",
        help=f"the excitation ({described(SIGNALS)}).",
    )
    parser.add_argument(
        "--periods",
        type=positive_float,
        default=1.0,
        help="length of the excitation in 10 s periods (default: 1).",
    )
    parser.add_argument(
        "--rate",
        type=positive_float,
        default=1000.0,
        help="sample rate in Hz (default: 1000, as in the paper).",
    )
    parser.add_argument(
        "--substeps",
        type=positive_int,
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
    parser.set_defaults(run=run)


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


def run(args: argparse.Namespace) -> int:
    choice = SIMULATE_MODELS[args.model]
    model = choice.build()
    overrides = _parse_params(args.param, model.parameter_names, args.model)
    if overrides:
        model = model.replace(**overrides)
    signal = SIGNALS[args.signal].build(args.periods, args.seed)
    csv_path, png_path = check_folder(
        "--out", args.out, ("simulation.csv", "loop.png"), args.force
    )
    require_matplotlib()

    stability = bibo_stability(model)
    if not stability:
        warn(
            f"parameters outside the BIBO-stable classes of Table 2 "
            f"({stability.reason}); the output may diverge."
        )
    path = sample(signal, args.rate)
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
    scale, y_unit = display_unit(choice.output_unit)
    loop = loop_figure(
        recording.u,
        {f"{type(model).__name__} ({args.model})": recording.y},
        xlabel="input u" + (f" [{choice.input_unit}]" if choice.input_unit else ""),
        ylabel="output y" + (f" [{y_unit}]" if y_unit else ""),
        title=f"{type(model).__name__} under {args.signal}: hysteresis loop",
        scale=scale,
    )
    save_figure(loop, png_path, overwrite=args.force)

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
