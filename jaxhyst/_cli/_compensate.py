"""`jaxhyst compensate`: the drive that makes a saved model follow a reference."""

import argparse
import math
from pathlib import Path

import numpy as np

from .._compensate import compensate
from .._evaluate import default_solver
from .._files import prepare_parent
from .._model_files import LoadedModel
from .._plots import require_matplotlib
from .._recording import Recording, RecordingError
from .._report import (
    COMPENSATION_FIGURES,
    display_unit,
    html_path,
    write_compensation_report,
)
from .._status import RESULTS, has_status
from ._evaluate import missing_column
from ._options import add_model_file_argument, column, load_model_file, warn
from ._outputs import check_files, print_written


_FIGURES = tuple(COMPENSATION_FIGURES.values())


def add_parser(subparsers) -> None:
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
    add_model_file_argument(parser)
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
        help="the reference column (default: the output column the model was "
        "fitted from, as its model file names it, else y; with --no-header: 1).",
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
        "--slew-limit",
        type=float,
        default=None,
        metavar="RATE",
        help="the amplifier's largest drive rate |du/dt| in drive units per second "
        "(e.g. 10000 for 10 V/ms): samples the drive reaches faster are reported "
        "(the stage will lag the prediction there), not smoothed away.",
    )
    parser.add_argument(
        "--report",
        default=None,
        metavar="PATH",
        help="write a Markdown report (tracking error, figures "
        "next to it: " + ", ".join(_FIGURES) + "), and the same report as "
        "self-contained HTML next to it (PATH with .html, figures embedded).",
    )
    parser.add_argument(
        "--force", action="store_true", help="replace existing outputs."
    )
    parser.set_defaults(run=run)


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
    limits = loaded.input_range
    if limits is None:
        raise ValueError(
            f"{args.model_file} does not record the input range it was fitted on; "
            "pass the drive's range with --limits LO,HI (e.g. --limits 0,150)."
        )
    return limits


def _read_reference(args: argparse.Namespace, loaded: LoadedModel) -> Recording:
    header = not args.no_header
    # Without --output: the output column the model was fitted from, else y.
    columns = loaded.columns if header and args.output is None else None
    default = "y" if columns is None else columns[1]
    output = column(args.output, default, 1, header, "output")
    try:
        return Recording.load(
            args.reference,
            time=column(args.time, "t", 0, header, "time"),
            input=output,
            output=output,
            header=header,
        )
    except RecordingError:
        if columns is not None:
            error = missing_column(args.reference, loaded, default, "--output")
            if error is not None:
                raise error from None
        raise


def run(args: argparse.Namespace) -> int:
    out = Path(args.out)
    report = Path(args.report) if args.report is not None else None
    outputs = [("--out", out)]
    if report is not None:
        outputs.append(("--report", report))
        outputs.append(("--report", html_path(report, "--report")))
        outputs += [("--report", report.parent / name) for name in _FIGURES]
    check_files(outputs, args.force)
    if report is not None:
        require_matplotlib()
    loaded = load_model_file(args.model_file)
    names = loaded.model.input_names
    if len(names) > 1:
        raise ValueError(
            f"{args.model_file}: {type(loaded.model).__name__} reads {len(names)} "
            f"inputs ({', '.join(names)}); compensate finds the one drive of a model "
            "of one input (a piezo model): pass such a model file."
        )
    reference = _read_reference(args, loaded)
    limits = _limits(args, loaded)
    result = compensate(
        loaded.model,
        reference.t,
        reference.y,
        limits=limits,
        slew_limit=args.slew_limit,
        solver=default_solver(loaded.model, reference),
        throw=False,
    )
    if has_status(result.result, RESULTS.nonfinite):
        raise ValueError(
            "the model diverged while following the reference; check that the "
            "reference is in the model's output units and inside its stroke."
        )
    tracking = result.tracking()
    scale, unit = display_unit(loaded.units["output"] or reference.output_unit)
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
        warn(
            f"{tracking['samples_at_limit']} of {reference.num_samples} samples need "
            f"a drive outside {limits[0]:g} to {limits[1]:g}: the model cannot reach "
            "the reference there (the drive is held at the limit); widen --limits "
            "if the amplifier allows."
        )
    if tracking["samples_over_slew"]:
        warn(
            f"{tracking['samples_over_slew']} of {reference.num_samples} samples need "
            f"the drive to move faster than --slew-limit {args.slew_limit:g} per s "
            f"(up to {tracking['max_slew_rate']:.4g} per s): the amplifier cannot "
            "follow it there, and the stage will lag the prediction; slow the "
            "reference down there or check the amplifier's slew rate."
        )
    prepare_parent(out)
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
        written += write_compensation_report(
            result,
            reference,
            report,
            model=loaded.model,
            model_file=args.model_file,
            reference_file=args.reference,
            output_unit=loaded.units["output"],
            overwrite=args.force,
        )
    print_written(written)
    return 0
