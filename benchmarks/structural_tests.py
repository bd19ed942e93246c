"""The structural diagnosis on real quasi-static cyclic tests: every record of
`jh.datasets.STRUCTURAL_TESTS` (RC columns and walls, a CLT rocking wall, a steel-plate
connection; imposed displacement -> restoring force).

For each record this script

1. runs `jh.diagnose(recording, key=..., family=jh.families.StructuralFamily())`: a
   plain Bouc-Wen base fitted on part of the cycles, effects (degradation, pinching,
   asymmetry, drift) adopted only if they lower the error on held-out whole cycles;
2. fits the plain Bouc-Wen model with `jh.identify` on the same fitted samples (the
   family's base template, bounds and solver), as a cross-check of the diagnosis's
   base;
3. if `jh.opensees_material` and `jaxhyst._opensees.opensees_force` exist and
   openseespy loads, exports the final model to its OpenSees material, drives it
   with the record's displacement and reports the largest difference from
   jaxhyst's final force, relative to max|F| (effects OpenSees lacks, such as
   drift and asymmetry, are dropped by the export and show up here).

It prints the machine and versions and a Markdown table: held-out RMS and NRMSD
(RMS / max|F| of the record) of the base and final models on the held-out cycles,
the findings in order with their held-out gains, beside them what the loops show
without a model (`jh.diagnosis.loop_indicators`: do they degrade, do they pinch,
with the numbers each verdict rests on), what stayed unexplained, and the
seconds; below it, where the findings and the loops disagree, why. `--out DIR` also writes the table (DIR/structural_tests.md) and one
before/after loop figure per record (DIR/<record>_loops.png: measured, base,
final force against displacement); `--json PATH` writes everything as JSON.
Existing outputs are never replaced without `--force`.

    python benchmarks/structural_tests.py --out jaxhyst-out/structural
    python benchmarks/structural_tests.py --records daniel chiu --particles 32 \\
        --iterations 50 --json structural.json

`--loops-only` prints just the loop indicators of the records (no diagnosis: a few
seconds for all eight), with each verdict's reason below the table:

    python benchmarks/structural_tests.py --loops-only
"""

import argparse
import importlib
import sys
import time
import traceback
from pathlib import Path
from typing import Any

import jax


jax.config.update("jax_enable_x64", True)

import _common as common  # noqa: E402
import numpy as np  # noqa: E402

import jaxhyst as jh  # noqa: E402


try:  # re-exported by jaxhyst once the structural loaders land in __init__
    from jaxhyst.datasets import STRUCTURAL_TESTS, load_structural_test  # noqa: E402
except ImportError:
    from jaxhyst._datasets import STRUCTURAL_TESTS, load_structural_test  # noqa: E402


TABLE = "structural_tests.md"


def parse_args(argv=None):
    parser = argparse.ArgumentParser(
        description=(__doc__ or "").split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    common.add_data_dir(parser, "the structural_* folders")
    parser.add_argument(
        "--records",
        nargs="+",
        choices=STRUCTURAL_TESTS,
        default=list(STRUCTURAL_TESTS),
        metavar="NAME",
        help=f"the records to run (default: all of {', '.join(STRUCTURAL_TESTS)})",
    )
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument(
        "--particles",
        type=int,
        default=None,
        help="swarm size of the fits and the diagnosis (default: the library's)",
    )
    parser.add_argument(
        "--iterations",
        type=int,
        default=None,
        help="swarm iterations of the fits and the diagnosis (default: the library's)",
    )
    parser.add_argument(
        "--no-opensees", action="store_true", help="skip the OpenSees comparison"
    )
    parser.add_argument(
        "--loops-only",
        action="store_true",
        help="print only the model-free loop indicators of the records (no "
        "diagnosis, no fit; --json writes them)",
    )
    parser.add_argument(
        "--out",
        metavar="DIR",
        default=None,
        help="write the Markdown table and the loop figures into DIR (created if "
        "missing)",
    )
    common.add_json(parser)
    common.add_force(parser)
    args = parser.parse_args(argv)
    for option in ("particles", "iterations"):
        value = getattr(args, option)
        if value is not None and value < (2 if option == "particles" else 1):
            parser.error(f"--{option} {value} is too small")
    return args


# ---------------------------------------------------------------------- inputs


def structural_api():
    """`(diagnose, StructuralFamily)`, or exit saying what is missing."""
    family = getattr(jh.families, "StructuralFamily", None)
    if family is None:
        raise SystemExit(
            "structural_tests: this jaxhyst has no jh.families.StructuralFamily (the "
            "structural diagnosis); update jaxhyst, or run it from a source tree "
            "that has jaxhyst/_diagnose with the structural family."
        )
    return jh.diagnose, family


def opensees_api():
    """`(opensees_material, opensees_force)`, or a string saying why not."""
    material = getattr(jh, "opensees_material", None)
    try:
        module = importlib.import_module("jaxhyst._opensees")
    except ImportError as error:
        return f"jaxhyst._opensees is missing ({error})"
    if material is None:
        material = getattr(module, "opensees_material", None)
    force = getattr(module, "opensees_force", None)
    if material is None or force is None:
        return "this jaxhyst has no opensees_material / opensees_force"
    return material, force


def loops_api():
    """`(loop_indicators, compare_loops)`, or exit saying what is missing."""
    try:
        module = importlib.import_module("jaxhyst._diagnose._loop_indicators")
    except ImportError:
        raise SystemExit(
            "structural_tests: this jaxhyst has no jh.diagnosis.loop_indicators (the "
            "model-free loop indicators); update jaxhyst."
        ) from None
    return module.loop_indicators, module.compare_loops


def percent(value: float, digits: int = 0) -> str:
    return "n/a" if not np.isfinite(value) else f"{100 * value:.{digits}f} %"


def loops_cells(loops) -> tuple[str, str]:
    """The degradation and pinching verdicts with the numbers they rest on."""
    worst = max((e for e in loops.envelope_loss if np.isfinite(e)), default=np.nan)
    degrade = (
        f"{loops.degradation.answer}: 2nd cycle {percent(loops.strength_loss)} "
        f"({loops.repeated_levels} levels), post-peak {percent(worst)}"
    )
    pinch = (
        f"{loops.pinching.answer}: F(0) {percent(loops.zero_force_ratio)}, energy "
        f"{percent(loops.energy_ratio)}, unloading "
        + (
            f"{loops.unloading_ratio:.1f}x"
            if np.isfinite(loops.unloading_ratio)
            else "n/a"
        )
    )
    return degrade, pinch


def loops_json(loops, agreement=()) -> dict:
    """The indicators as JSON (without the per-cycle list), with the agreement."""
    data = {k: v for k, v in loops.to_dict().items() if k != "cycles"}
    if agreement:
        data["agreement"] = [a.to_dict() for a in agreement]
    return data


# ----------------------------------------------------------------- one record


def heldout_rms(y: np.ndarray, predicted: np.ndarray, mask: np.ndarray) -> float:
    residual = np.asarray(predicted, dtype=np.float64) - y
    return float(np.sqrt(np.mean(residual[mask] ** 2)))


def plain_fit(recording, family, mask, key, swarm_kwargs) -> dict:
    """The plain Bouc-Wen base by `jh.identify`, on the diagnosis's fitted samples."""
    start = time.perf_counter()
    fit = jh.identify(
        family.base_template(),
        recording,
        key=key,
        space=family.base_space(recording),
        solver=family.solver(recording),
        weights=jax.numpy.asarray((~mask).astype(np.float64)),
        **{"swarm": family.base_swarm(), **swarm_kwargs},
    )
    predicted = np.asarray(fit.predicted)
    return {
        "model": type(fit.model).__name__,
        "parameters": {k: float(v) for k, v in fit.model.parameters().items()},
        "predicted": predicted,
        "heldout_rms": heldout_rms(recording.y, predicted, mask),
        "seconds": time.perf_counter() - start,
    }


def opensees_check(api, diagnosis, recording) -> dict:
    """The final model's OpenSees material under the record's displacement."""
    if isinstance(api, str):
        return {"skipped": api}
    opensees_material, opensees_force = api
    try:
        material = opensees_material(diagnosis.final_model)
    except (TypeError, ValueError) as error:
        return {"skipped": f"no OpenSees material for the final model ({error})"}
    # About 2 million strain increments in all: fine where samples are few.
    substeps = int(min(200, max(10, 2_000_000 // recording.num_samples)))
    start = time.perf_counter()
    try:
        force = opensees_force(material, recording.u, substeps)
    except ImportError as error:
        return {"skipped": f"openseespy cannot load ({error})"}
    final = np.asarray(diagnosis.final_predicted, dtype=np.float64)
    scale = float(np.max(np.abs(recording.y)))
    return {
        "material": material.material,
        "command": material.command,
        "exact": bool(material.exact),
        "dropped": list(material.dropped),
        "substeps": substeps,
        "max_mismatch": float(np.max(np.abs(force - final))),
        "max_mismatch_relative": float(np.max(np.abs(force - final)) / scale),
        "seconds": time.perf_counter() - start,
    }


def run_record(name, args, api, opensees, key) -> dict:
    diagnose, family_class = api
    recording = load_structural_test(name, data_dir=args.data_dir)
    y = recording.y
    scale = float(np.max(np.abs(y)))
    reversals = recording.reversals()
    common.log(
        f"{name}: {recording.num_samples} points, {reversals.size} reversals; "
        "diagnosing"
    )
    swarm_kwargs = {}
    if args.particles is not None or args.iterations is not None:
        sizes = {"num_particles": 100, "num_iterations": 200}
        if args.particles is not None:
            sizes["num_particles"] = args.particles
        if args.iterations is not None:
            sizes["num_iterations"] = args.iterations
        swarm_kwargs["swarm"] = jh.MPSO(**sizes)
    family = family_class()
    start = time.perf_counter()
    diagnosis = diagnose(
        recording, key=jax.random.fold_in(key, 0), family=family, **swarm_kwargs
    )
    wall = time.perf_counter() - start
    loop_indicators, compare_loops = loops_api()
    loops = getattr(diagnosis, "loops", None) or loop_indicators(recording)
    agreement = getattr(diagnosis, "loop_agreement", None) or compare_loops(
        diagnosis.effects,
        loops,
        undecided=getattr(diagnosis, "undecided", ()),
    )
    mask = np.asarray(diagnosis.heldout, dtype=bool)
    base = np.asarray(diagnosis.base_predicted, dtype=np.float64)
    final = np.asarray(diagnosis.final_predicted, dtype=np.float64)
    base_rms = heldout_rms(y, base, mask)
    final_rms = heldout_rms(y, final, mask)
    findings = []
    for finding in diagnosis.findings:
        v = finding.validation
        before, after = float(v.heldout_rmse_before), float(v.heldout_rmse_after)
        findings.append(
            {
                "effect": finding.effect,
                "evidence": finding.evidence,
                "heldout_rmse_before": before,
                "heldout_rmse_after": after,
                "heldout_gain_percent": 100 * (1 - after / before),
            }
        )
    common.log(f"{name}: plain Bouc-Wen fit on the same fitted samples")
    plain = plain_fit(recording, family, mask, jax.random.fold_in(key, 1), swarm_kwargs)
    check = {"skipped": "--no-opensees"}
    if not args.no_opensees:
        common.log(f"{name}: OpenSees comparison")
        check = opensees_check(opensees, diagnosis, recording)
    return {
        "record": name,
        "recording": recording,
        "points": recording.num_samples,
        "reversals": int(reversals.size),
        "units": {"input": recording.input_unit, "output": recording.output_unit},
        "max_abs_force": scale,
        "heldout_points": int(mask.sum()),
        "base": {"heldout_rms": base_rms, "heldout_nrmsd": base_rms / scale},
        "findings": findings,
        "final": {
            "model": type(diagnosis.final_model).__name__,
            "heldout_rms": final_rms,
            "heldout_nrmsd": final_rms / scale,
        },
        "unexplained": [
            f"{u.description} ({u.resembles})" for u in diagnosis.unexplained
        ],
        "ambiguities": [a.statement for a in diagnosis.ambiguities],
        "loops": loops_json(loops, agreement),
        "loop_cells": loops_cells(loops),
        "plain_fit": {
            "model": plain["model"],
            "parameters": plain["parameters"],
            "heldout_rms": plain["heldout_rms"],
            "heldout_nrmsd": plain["heldout_rms"] / scale,
            "seconds": plain["seconds"],
        },
        "opensees": check,
        "seconds": float(diagnosis.seconds),
        "wall_seconds": wall,
        "arrays": {"base": base, "final": final, "plain": plain["predicted"]},
        "heldout": mask,
    }


# -------------------------------------------------------------------- outputs


def loop_figure(path: Path, result: dict) -> None:
    from matplotlib.figure import Figure

    recording = result["recording"]
    u, y = recording.u, recording.y
    xunit = f" [{recording.input_unit}]" if recording.input_unit else ""
    yunit = f" [{recording.output_unit}]" if recording.output_unit else ""
    figure = Figure(figsize=(11, 4.8), layout="constrained")
    axes = figure.subplots(1, 2, sharex=True, sharey=True)
    panels = (
        ("base", "plain Bouc-Wen (base)", result["base"], "C0"),
        ("final", f"final: {result['final']['model']}", result["final"], "C3"),
    )
    effects = ", ".join(f["effect"] for f in result["findings"]) or "no findings"
    for ax, (key, label, summary, color) in zip(axes, panels, strict=True):
        ax.plot(u, y, color="0.6", lw=0.8, label="measured")
        ax.plot(u, result["arrays"][key], color=color, lw=0.8, label=label)
        ax.set_xlabel(f"displacement{xunit}")
        ax.set_title(
            f"{label}: held-out NRMSD {100 * summary['heldout_nrmsd']:.2f} %",
            fontsize=10,
        )
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", fontsize=8)
    axes[0].set_ylabel(f"force{yunit}")
    figure.suptitle(
        f"{result['record']}: {result['points']} points, {effects}", fontsize=11
    )
    figure.savefig(path, dpi=110)


def cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def markdown(results: list[dict], info: dict) -> str:
    machine, versions = common.machine_lines(info)
    lines = [
        "# Structural diagnosis on real cyclic tests",
        "",
        machine,
        "",
        versions,
        "",
        "RMS and NRMSD (RMS / max|F|) on the held-out cycles; gains are the drop of "
        "the held-out RMS when the effect was adopted; plain BW: `jh.identify` of "
        "the base model on the same fitted samples; OpenSees: max |F_OpenSees - "
        "F_final| / max|F|.",
        "",
        "Loops: what the loops show without a model (`jh.diagnosis."
        "loop_indicators`): degrade, with the median loss of force at equal "
        "displacement on a level's second cycle and the loss past the envelope's "
        "peak; pinch, with the force at zero displacement over the peak force, the "
        "energy over the rectangle's and the unloading stiffness over the secant "
        "(at the largest amplitudes).",
        "",
        "| record | points | reversals | base RMS | base NRMSD | findings (held-out "
        "gain) | loops: degrade | loops: pinch | final RMS | final NRMSD | "
        "unexplained | plain BW NRMSD | OpenSees | diagnosis s |",
        "|---|---:|---:|---:|---:|---|---|---|---:|---:|---|---:|---|---:|",
    ]
    for r in results:
        if "error" in r:
            lines.append(
                f"| {r['record']} | | | | | failed: {cell(r['error'])} "
                "| | | | | | | | |"
            )
            continue
        unit = f" {r['units']['output']}" if r["units"]["output"] else ""
        findings = ", ".join(
            f"{f['effect']} ({f['heldout_gain_percent']:+.1f} %)" for f in r["findings"]
        )
        check = r["opensees"]
        if "skipped" in check:
            opensees = f"skipped: {check['skipped']}"
        else:
            dropped = (
                f", dropped {', '.join(check['dropped'])}" if check["dropped"] else ""
            )
            opensees = (
                f"{check['material']}: {100 * check['max_mismatch_relative']:.2g} %"
                f"{dropped}"
            )
        lines.append(
            "| "
            + " | ".join(
                [
                    r["record"],
                    str(r["points"]),
                    str(r["reversals"]),
                    f"{r['base']['heldout_rms']:.4g}{unit}",
                    f"{100 * r['base']['heldout_nrmsd']:.2f} %",
                    cell(findings or "none"),
                    cell(r["loop_cells"][0]),
                    cell(r["loop_cells"][1]),
                    f"{r['final']['heldout_rms']:.4g}{unit}",
                    f"{100 * r['final']['heldout_nrmsd']:.2f} %",
                    cell("; ".join(r["unexplained"]) or "none"),
                    f"{100 * r['plain_fit']['heldout_nrmsd']:.2f} %",
                    cell(opensees),
                    f"{r['seconds']:.0f}",
                ]
            )
            + " |"
        )
    notes = [
        f"- {r['record']}: {cell(a)}" for r in results for a in r.get("ambiguities", [])
    ]
    if notes:
        lines += ["", "Ambiguities:", "", *notes]
    differ = [
        f"- {r['record']}: {cell(a['statement'])}"
        for r in results
        for a in r.get("loops", {}).get("agreement", [])
        if a["agree"] is False
    ]
    if differ:
        lines += ["", "Findings and loops disagree:", "", *differ]
    return "\n".join(lines) + "\n"


def loops_markdown(rows: list[tuple[str, tuple[int, Any]]]) -> str:
    """The `--loops-only` table: per record its cycles and the two verdicts with
    their numbers, then each verdict's reason."""
    lines = [
        "| record | points | cycles (levels, repeated) | degrade | 2nd-cycle loss "
        "| post-peak loss | pinch | F(0) / peak | energy / rectangle | "
        "unloading / secant |",
        "|---|---:|---:|---|---:|---:|---|---:|---:|---:|",
    ]
    reasons = []
    for name, (points, loops) in rows:
        worst = max((e for e in loops.envelope_loss if np.isfinite(e)), default=np.nan)
        unloading = (
            f"{loops.unloading_ratio:.1f}"
            if np.isfinite(loops.unloading_ratio)
            else "n/a"
        )
        lines.append(
            "| "
            + " | ".join(
                [
                    name,
                    str(points),
                    f"{len(loops.cycles)} ({len(loops.levels)}, "
                    f"{loops.repeated_levels})",
                    loops.degradation.answer,
                    percent(loops.strength_loss, 1),
                    percent(worst),
                    loops.pinching.answer,
                    percent(loops.zero_force_ratio),
                    percent(loops.energy_ratio),
                    unloading,
                ]
            )
            + " |"
        )
        reasons += [
            f"- {name}, degrade: {cell(loops.degradation.reason)}",
            f"- {name}, pinch: {cell(loops.pinching.reason)}",
        ]
    return "\n".join([*lines, "", *reasons]) + "\n"


def loops_only(args) -> int:
    """`--loops-only`: the loop indicators of every record, no diagnosis."""
    loop_indicators, _ = loops_api()
    rows = []
    for name in args.records:
        recording = load_structural_test(name, data_dir=args.data_dir)
        rows.append((name, (recording.num_samples, loop_indicators(recording))))
    print()
    print(loops_markdown(rows))
    if args.json is not None:
        common.write_json(
            {
                "machine": common.machine_info(),
                "records": [
                    {"record": name, "points": points, "loops": loops_json(loops)}
                    for name, (points, loops) in rows
                ],
            },
            args.json,
        )
    return 0


def json_ready(results: list[dict], info: dict, args) -> dict:
    drop = ("recording", "arrays", "heldout", "loop_cells")
    return {
        "machine": info,
        "settings": {
            "seed": args.seed,
            "particles": args.particles,
            "iterations": args.iterations,
        },
        "records": [{k: v for k, v in r.items() if k not in drop} for r in results],
    }


def main(argv=None) -> int:
    args = parse_args(argv)
    if args.loops_only:
        common.output_paths(args.json, None, [], force=args.force)
        args.data_dir = common.data_dir(args.data_dir)
        common.print_machine(common.machine_info(devices=False))
        print(f"data: {args.data_dir}")
        return loops_only(args)
    api = structural_api()
    names = [TABLE, *(f"{name}_loops.png" for name in args.records)]
    common.output_paths(args.json, args.out, names, force=args.force)
    if args.out is not None:
        common.require_matplotlib("--out needs", "")
    args.data_dir = common.data_dir(args.data_dir)
    opensees = "--no-opensees" if args.no_opensees else opensees_api()
    if isinstance(opensees, str) and not args.no_opensees:
        common.log(f"OpenSees comparison skipped: {opensees}")

    info = common.machine_info("matplotlib", "openseespy")
    common.print_machine(info)
    print(f"data: {args.data_dir}")

    key = jax.random.key(args.seed)
    results, failed, written = [], False, []
    for name in args.records:
        # A record's key is its place in the catalogue, not in --records: the same
        # record gets the same key whichever others run beside it.
        record_key = jax.random.fold_in(key, STRUCTURAL_TESTS.index(name))
        try:
            result = run_record(name, args, api, opensees, record_key)
        except FileNotFoundError as error:
            raise SystemExit(f"structural_tests: {error}") from None
        except Exception as error:  # report it in the table and go on
            traceback.print_exc()
            failed = True
            result = {"record": name, "error": f"{type(error).__name__}: {error}"}
        results.append(result)
        if args.out is not None and "error" not in result:
            out = Path(args.out)
            out.mkdir(parents=True, exist_ok=True)
            loop_figure(out / f"{name}_loops.png", result)
            written.append(out / f"{name}_loops.png")

    table = markdown(results, info)
    print()
    print(table)
    if args.out is not None:
        Path(args.out).mkdir(parents=True, exist_ok=True)
        (Path(args.out) / TABLE).write_text(table)
        written.append(Path(args.out) / TABLE)
    for path in written:
        print(f"wrote {path}")
    if args.json is not None:
        common.write_json(json_ready(results, info, args), args.json)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
