"""`jaxhyst fit`: identify a model from recordings; summary, JSON, figures."""

import argparse
import dataclasses
from pathlib import Path

from .._evaluate import default_solver
from .._identification._corrected import CORRECTED_STAGES, identify_corrected
from .._identification._identify import Fit, identify
from .._model_files import EMBEDDED_KEY, model_file_dict
from .._opensees import opensees_json
from .._plots import require_matplotlib
from .._recording import Recording
from .._report import FIT_FIGURES, fit_summary, write_fit_figures
from .._status import RESULTS, has_status, status_name
from .._swarm import MPSO
from ._choices import FIT_MODELS, described, prng_key
from ._evaluate import columns_by_name
from ._options import (
    add_recording_options,
    add_swarm_options,
    load_recordings,
    swarm as swarm_of,
    window,
    window_line,
)
from ._outputs import check_files, check_folder, print_written, write_json


def add_parser(subparsers) -> None:
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
    add_recording_options(parser, several=True)
    parser.add_argument(
        "--model",
        choices=tuple(FIT_MODELS),
        default="piezo",
        help=f"the model to identify (default: piezo; {described(FIT_MODELS)}).",
    )
    add_swarm_options(parser, presets=True)
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
    parser.set_defaults(run=run)


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


def _solver(model, recordings: list[Recording]):
    """The default solver of the recording that needs the most RK4 substeps (the
    one with the longest sample interval for a stiff model): one solver for all
    of them, each simulated at its own sample interval."""
    return max((default_solver(model, r) for r in recordings), key=lambda s: s.substeps)


def run(args: argparse.Namespace) -> int:
    swarm = swarm_of(args)
    outputs: list[tuple[str, Path]] = []
    json_path = Path(args.json) if args.json is not None else None
    if json_path is not None:
        outputs.append(("--json", json_path))
    check_files(outputs, args.force)
    recordings = load_recordings(args)
    plots = Path(args.plots) if args.plots is not None else None
    folders = [] if plots is None else _plot_folders(plots, recordings)
    for folder in folders:
        check_folder("--plots", folder, FIT_FIGURES.values(), args.force)
    if folders:
        require_matplotlib()

    key = prng_key(args.seed)
    stages = None
    template = FIT_MODELS[args.model].template
    fit: Fit
    if template is None:
        fit, stages = _identify_corrected(recordings, key, swarm)
    else:
        model = template()
        fit = identify(
            model,
            recordings,
            key=key,
            swarm=swarm,
            solver=_solver(model, recordings),
            progress=True,
            throw=False,
        )
    if has_status(fit.result, RESULTS.nonfinite):
        raise ValueError(
            "the fitted model's output is not finite; try another --seed, a larger "
            "swarm, or check the recording."
        )
    for recording in recordings:
        print(
            f"recording: {recording.name}, {recording.num_samples} samples at "
            f"{recording.sample_rate:g} Hz over {recording.duration:g} s"
        )
        line = window_line(args, recording)
        if line is not None:
            print(line)
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
        data["window"] = window(args, recordings[0])
        if fit.model.has_opensees_material:
            data.update(opensees_json(fit.model, recordings[0]))
        if stages is not None:
            data["stages"] = stages
        # The model file (jh.load_model and 'jaxhyst evaluate' read it from here).
        data[EMBEDDED_KEY] = model_file_dict(
            fit.model, recording=recordings, columns=columns_by_name(args)
        )
        write_json(data, json_path, args.force)
    for i, (recording, folder) in enumerate(zip(recordings, folders)):
        written = write_fit_figures(
            fit.for_recording(i),
            recording,
            folder,
            overwrite=args.force,
            label=args.model,
        )
        print_written(written.values())
    return 0
