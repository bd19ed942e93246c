"""`jaxhyst evaluate`: a saved model on recordings, and its errors."""

import argparse
from pathlib import Path

import numpy as np

from .._evaluate import predict
from .._metrics import error_metrics
from .._model_files import LoadedModel
from .._recording import Recording, RecordingError, column_names
from .._report import display_unit
from ._options import (
    add_model_file_argument,
    add_recording_options,
    load_model_file,
    load_recording,
    window,
    window_line,
)
from ._outputs import check_files, write_json


def add_parser(subparsers) -> None:
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
    add_model_file_argument(parser)
    add_recording_options(parser, several=True)
    parser.epilog = (
        "Without --input (--output), the inputs (output) are read from the columns "
        "the model was fitted from, by the names its model file records (e.g. u and "
        "v for an MR damper); files that record none read u (y) as before."
    )
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
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    json_path = Path(args.json) if args.json is not None else None
    if json_path is not None:
        check_files([("--json", json_path)], args.force)
    loaded = load_model_file(args.model_file)
    model = loaded.model
    recordings, columns = load_for_model(args, loaded)
    for path, recording in zip(args.recording, recordings):
        loaded.check_units(recording, path)

    results = []
    for path, recording in zip(args.recording, recordings):
        y = predict(model, recording)
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
    if columns is not None:
        print(
            f"columns: {', '.join(columns[0])} -> {columns[1]} (the model's, where "
            "--input/--output do not pick others)"
        )
    scale, unit = display_unit(loaded.units["output"] or recordings[0].output_unit)
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
        line = window_line(args, recording)
        if line is not None:
            print(f"  {line}")
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
            "window": window(args, recordings[0]),
        }
        write_json(data, json_path, args.force)
    return 0


# ----------------------------------------------------- the columns of the model


def columns_by_name(args: argparse.Namespace) -> bool:
    """Whether the recordings were read by column name, so that their input and
    output names are columns another file can be read by: not with --no-header or
    --no-time, nor with an --input or --output given as an index."""
    if args.no_header or args.no_time:
        return False
    given = [*(args.input or ()), *(() if args.output is None else (args.output,))]
    return not any(text.strip().isdigit() for text in given)


def model_columns(
    args: argparse.Namespace, loaded: LoadedModel
) -> tuple[tuple[str, ...], str] | None:
    """The columns the model was fitted from (`LoadedModel.columns`), where the
    command reads files by column name; None otherwise (the defaults u and y)."""
    if args.no_header or args.no_time:
        return None
    return loaded.columns


def missing_column(
    path: str, loaded: LoadedModel, name: str, option: str
) -> ValueError | None:
    """The error for a file `path` that lacks the column `name` the model file
    names (read by default, `option` picks another), None if it has it or its
    columns cannot be listed."""
    have = column_names(path)
    columns = loaded.columns
    if have is None or name in have or columns is None:
        return None
    inputs, output = columns
    if option == "--input":
        role = f"{loaded.model.input_names[inputs.index(name)]} input"
        flags = " ".join(
            "--input NAME" if each == name else f"--input {each}" for each in inputs
        )
        fix = (
            "name the column to read with --input NAME, once per input in order "
            f"({flags})"
        )
    else:
        role = "output"
        fix = "name the output column with --output NAME"
    return ValueError(
        f"{path} has no column {name!r}, the model's {role} (it was fitted from the "
        f"columns {', '.join(inputs)} -> {output}); its columns are "
        f"{', '.join(have) or 'none'}: {fix}."
    )


def load_for_model(
    args: argparse.Namespace, loaded: LoadedModel
) -> tuple[list[Recording], tuple[tuple[str, ...], str] | None]:
    """Every recording named on the command line, its inputs and output read from
    the columns the model was fitted from where --input / --output are not given;
    and the columns read (None where the model file names none, or --input and
    --output both pick them)."""
    columns = model_columns(args, loaded)
    if columns is None or (args.input is not None and args.output is not None):
        return [load_recording(args, path) for path in args.recording], None
    inputs, output = columns
    defaults = argparse.Namespace(**vars(args))
    if args.input is None:
        defaults.input = list(inputs)
    if args.output is None:
        defaults.output = output
    recordings = []
    for path in args.recording:
        try:
            recordings.append(load_recording(defaults, path))
        except RecordingError:
            for name, option, given in (
                *((name, "--input", args.input) for name in inputs),
                (output, "--output", args.output),
            ):
                error = (
                    None
                    if given is not None
                    else missing_column(path, loaded, name, option)
                )
                if error is not None:
                    raise error from None
            raise
    return recordings, (tuple(defaults.input), defaults.output)
