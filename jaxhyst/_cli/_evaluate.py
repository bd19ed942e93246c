"""`jaxhyst evaluate`: a saved model on recordings, and its errors."""

import argparse
from pathlib import Path

import numpy as np

from .._evaluate import predict
from .._metrics import error_metrics
from .._report import display_unit
from ._options import (
    add_model_file_argument,
    add_recording_options,
    load_model_file,
    load_recordings,
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
    recordings = load_recordings(args)
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
