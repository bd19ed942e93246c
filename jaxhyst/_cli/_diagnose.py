"""`jaxhyst diagnose`: find the physics a model leaves out of a recording;
summary, JSON, figures, Markdown and HTML report."""

import argparse
import dataclasses
from pathlib import Path

from .._diagnose._diagnose import diagnose
from .._diagnose._families import EFFECT_NAMES, DamperFamily
from .._diagnose._policy import AdoptionPolicy
from .._files import prepare_parent
from .._model_files import EMBEDDED_KEY, model_file_dict
from .._plots import require_matplotlib
from .._recording import Recording
from .._report import (
    DIAGNOSIS_FIGURES,
    diagnosis_summary,
    html_path,
    write_diagnosis_figures,
    write_diagnosis_report,
)
from ._choices import family, prng_key
from ._evaluate import columns_by_name
from ._options import (
    add_recording_options,
    add_swarm_options,
    diagnosis_swarm,
    load_recordings,
    window,
    window_line,
)
from ._outputs import (
    check_files,
    check_folder,
    print_written,
    write_json,
)


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "diagnose",
        help="find the physics a model leaves out of a recording (piezo, "
        "structural or MR damper family); summary, JSON, figures, Markdown and HTML "
        "report",
        description=(
            "Fit the family's base model (--model: the quasi-static piezo model of "
            "eq. 7-8, the structural Bouc-Wen element or the MR damper of fixed "
            "field) on part of a recording, score every catalogue effect on its "
            "residual (piezo: " + ", ".join(EFFECT_NAMES) + "), "
            "refit the strongest, and keep an effect only if it lowers the error on "
            "held-out data by more than the noise; repeat. Effects the record cannot "
            "show (a damper tested at one command) are not asked about, and the "
            "report says why. Prints the findings with "
            "their evidence, the RMSE before/after and any ambiguities; --json, "
            "--plots and --report save them. Several recordings of one specimen (same "
            "units and sample rate) are diagnosed as one: one model, held-out data "
            "in each, each simulated from rest, their errors under 'per_recording' "
            "in the JSON. Existing outputs are never replaced without --force."
        ),
    )
    add_recording_options(parser, several=True)
    parser.add_argument(
        "--model",
        default="piezo",
        metavar="NAME",
        help="the family: 'piezo' (default; PiezoBoucWen with asymmetry, input "
        "bias, rate dependence, creep, dynamics, drift), 'bouc-wen' (structural "
        "cyclic tests, columns t,u,y = pseudo time, displacement, force: BoucWen with "
        "degradation, pinching, asymmetry, drift; the JSON then carries the matching "
        "OpenSees material under 'opensees') or 'mr-damper' (MR dampers, columns "
        "t,u,v,y = time, displacement, command, force, the inputs read as --input u "
        "--input v unless given or saved in the file: BoucWenDamper with field "
        "dependence, driver lag, roll-off, offset, asymmetry).",
    )
    parser.add_argument(
        "--command-level",
        type=float,
        default=None,
        metavar="V",
        help="--model mr-damper only: the records have no command column because the "
        "test ran at one fixed command; V is that level (the field's effects are then "
        "not asked about, and the report says why).",
    )
    parser.add_argument(
        "--min-heldout-gain",
        type=float,
        default=None,
        metavar="FRACTION",
        help="the smallest drop of the held-out mean squared error an effect must "
        "bring to be adopted (default: the family's policy, 0.05). Lower it on long, "
        "quiet records (tens of thousands of samples) to report smaller effects; the "
        "drop must still beat the record's noise.",
    )
    add_swarm_options(parser, presets=False)
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
        "folder PATH-stem_figures next to the report), and the same report as "
        "self-contained HTML next to it (PATH with .html, figures embedded).",
    )
    parser.add_argument(
        "--force",
        action="store_true",
        help="replace the JSON file, figures and report if they already exist.",
    )
    parser.set_defaults(run=run)


def _load(args: argparse.Namespace, chosen) -> list[Recording]:
    """The recordings; for the damper family, whose records carry a command beside
    the displacement, the inputs default to the columns u then v where neither
    --input nor the file names them."""
    if args.command_level is not None:
        if not isinstance(chosen, DamperFamily):
            raise ValueError(
                f"--command-level is for --model mr-damper, not --model {args.model}; "
                "drop it."
            )
        recordings = load_recordings(args)
        for each in recordings:
            if each.num_inputs > 1:
                raise ValueError(
                    f"--command-level: {each.name} already has a command column "
                    f"({each.input_names[1]!r}); drop --command-level to use it."
                )
        return [r.with_input("command", args.command_level) for r in recordings]
    recordings = load_recordings(args)
    if (
        isinstance(chosen, DamperFamily)
        and args.input is None
        and not (args.no_time or args.no_header)
        and any(r.num_inputs < 2 for r in recordings)
    ):
        args.input = ["u", "v"]
        recordings = load_recordings(args)
    return recordings


def _policy(args: argparse.Namespace, chosen) -> AdoptionPolicy | None:
    """The family's default policy with --min-heldout-gain, or None (the default)."""
    if args.min_heldout_gain is None:
        return None
    if not 0 <= args.min_heldout_gain < 1:
        raise ValueError(
            f"--min-heldout-gain {args.min_heldout_gain}: must be a fraction in "
            "[0, 1) of the held-out mean squared error, e.g. 0.02."
        )
    return dataclasses.replace(
        chosen.default_policy(), min_heldout_gain=args.min_heldout_gain
    )


def run(args: argparse.Namespace) -> int:
    chosen = family(args.model)
    policy = _policy(args, chosen)
    swarm = diagnosis_swarm(args)
    files: list[tuple[str, Path]] = []
    json_path = Path(args.json) if args.json is not None else None
    report_path = Path(args.report) if args.report is not None else None
    if json_path is not None:
        files.append(("--json", json_path))
    if report_path is not None:
        files.append(("--report", report_path))
        files.append(("--report", html_path(report_path, "--report")))
    check_files(files, args.force)
    plots = Path(args.plots) if args.plots is not None else None
    if plots is None and report_path is not None:
        plots = report_path.parent / f"{report_path.stem}_figures"
    if plots is not None:
        check_folder("--plots", plots, DIAGNOSIS_FIGURES.values(), args.force)
        require_matplotlib()
    recordings = _load(args, chosen)
    # Several recordings are diagnosed as one specimen; the summary, figures and
    # report read their samples one after another (the joined record; at several
    # sample rates its time runs at the finest one's step, each test kept whole).
    recording = Recording.join(recordings, mixed_rates=True)

    diagnosis = diagnose(
        recordings if len(recordings) > 1 else recording,
        key=prng_key(args.seed),
        family=chosen,
        policy=policy,
        swarm=swarm,
        progress=True,
    )
    if policy is not None:
        print(
            f"minimum held-out gain: {policy.min_heldout_gain:.3g} (--min-heldout-gain)"
        )
    line = window_line(args, recording)
    if line is not None:
        print(line)
    if len({round(r.sample_rate, 6) for r in recordings}) > 1:
        for each in recordings:
            print(
                f"recording: {each.name}, {each.num_samples} samples at "
                f"{each.sample_rate:g} Hz over {each.duration:g} s (simulated at its "
                "own rate; the joined record below runs at the finest)"
            )
    print(diagnosis_summary(diagnosis, recording))
    if json_path is not None:
        data = diagnosis.to_dict()
        data["window"] = window(args, recording)
        # The final model; its column names for evaluate unless --command-level
        # gave the command.
        data[EMBEDDED_KEY] = model_file_dict(
            diagnosis.final_model,
            recording=recordings,
            family=diagnosis.family,
            effects=diagnosis.effects,
            columns=columns_by_name(args) and args.command_level is None,
        )
        write_json(data, json_path, args.force)
    figures = {}
    if plots is not None:
        figures = write_diagnosis_figures(
            diagnosis, recording, plots, overwrite=args.force
        )
        print_written(figures.values())
    if report_path is not None:
        extra = {"diagnosis JSON": json_path} if json_path is not None else None
        write_diagnosis_report(
            diagnosis,
            recording,
            prepare_parent(report_path),
            figures,
            overwrite=args.force,
            files=extra,
        )
        print(f"wrote {report_path}")
        print(f"wrote {html_path(report_path)}")
    return 0
