"""Benchmark: the MR damper family on Dyke's measured white-noise tests.

Two white-noise characterisation tests of a prototype MR damper (S. Dyke,
NEES-2012-1158; `jh.datasets.load_mr_damper`): displacement [cm] and command [V] ->
force [N] at 3004.8 Hz, "ranran_50" (24.6 s) and "ransim_u" (20.0 s). For each direction
(fit on one record, validate on the other) this script

1. diagnoses the fit record with `jh.families.DamperFamily()` (its default adoption
   policy, or `--min-heldout-gain`): a Bouc-Wen damper of fixed field, then the effects the
   record shows beyond it, each adopted only when it lowers the error on the fit
   record's held-out blocks;
2. simulates every model the diagnosis moved to (`Diagnosis.steps`: the base, each
   adoption, the final model) on **both** records, from rest, and reports each
   step's force RMSE and Spencer et al.'s normalised errors (below);
3. for each finding, its gain on the record it was not fitted to (the validation
   RMSE before and after it was added);
4. draws the force against velocity and against displacement on one second of the
   validation record: measured, Spencer's published model, the base, the final.

The published anchor: Spencer, Dyke, Sain and Carlson (1997)'s "modified
Bouc-Wen" parameters for their prototype (`jh.SpencerDamper.spencer_1997()`),
simulated on the same records. They are published in N, cm, s and V, the units
these records come in, so no conversion is needed (a record in m would scale c0,
c1, k0, k1 and alpha by 100, beta and gamma by 100^n, and x0 by 1/100); they were
identified on another test of a similar damper, not on these records.

Spencer et al.'s normalised errors (their eq. 14-16): E_t = eps_t/sigma_t with
eps_t^2 = int (F_meas - F_pred)^2 dt and sigma_t^2 = int (F_meas - mean F)^2 dt;
E_x and E_xdot weight both integrals by |xdot| and |xddot| (here the weighted
variance is the denominator too, so each is dimensionless; the velocity and
acceleration are central differences of the displacement).

    python benchmarks/mr_damper.py                          # both directions
    python benchmarks/mr_damper.py --fit ranran_50          # one direction
    python benchmarks/mr_damper.py --seconds 3 --no-figures # smoke run (3 s each)
"""

import argparse
import dataclasses
import sys
import time
from typing import Any

import jax
import numpy as np


jax.config.update("jax_enable_x64", True)

import _common as common  # noqa: E402

import jaxhyst as jh  # noqa: E402


TESTS = ("ranran_50", "ransim_u")
LOOP_SECONDS = 1.0


def spencer_errors(recording: jh.Recording, predicted: np.ndarray) -> dict[str, float]:
    """Force RMSE [N], NRMSD and Spencer et al.'s E_t, E_x, E_xdot (module doc)."""
    force = np.asarray(recording.y)
    x = np.asarray(recording.u)
    velocity = np.gradient(x, recording.dt)
    acceleration = np.gradient(velocity, recording.dt)
    error2 = (force - predicted) ** 2
    spread2 = (force - np.mean(force)) ** 2

    def normalised(weight: np.ndarray) -> float:
        return float(np.sqrt(np.sum(error2 * weight) / np.sum(spread2 * weight)))

    out = {k: float(v) for k, v in jh.error_metrics(force, predicted).items()}
    return {
        "rmse": out["rmse"],
        "nrmsd": out["nrmsd"],
        "E_t": normalised(np.ones_like(x)),
        "E_x": normalised(np.abs(velocity)),
        "E_xdot": normalised(np.abs(acceleration)),
    }


def load(name: str, args) -> jh.Recording:
    recording = jh.datasets.load_mr_damper(name, data_dir=args.data_dir)
    if args.seconds is not None:
        recording = recording.segment(None, float(recording.t[0]) + args.seconds)
    return recording


def finding_gains(steps: list[dict], findings: list[str]) -> list[dict[str, Any]]:
    """Per finding, the validation RMSE of the last step before it was added and of
    the model it converged to (the step after "added", when it is a convergence
    refit), and the fit record's held-out RMSE likewise."""
    rows = []
    for effect in findings:
        added = next(
            (i for i, s in enumerate(steps) if s["step"].startswith(f"{effect} added")),
            None,
        )
        if added is None or added == 0:
            continue
        after = added
        following = steps[added + 1] if added + 1 < len(steps) else None
        if following is not None and following["step"].startswith(
            f"refit converged with {effect}"
        ):
            after = added + 1
        before = steps[added - 1]
        rows.append(
            {
                "effect": effect,
                "heldout_rmse_before": before["heldout_rmse"],
                "heldout_rmse_after": steps[after]["heldout_rmse"],
                "validation_rmse_before": before["validation"]["rmse"],
                "validation_rmse_after": steps[after]["validation"]["rmse"],
                "validation_gain": 1.0
                - steps[after]["validation"]["rmse"] / before["validation"]["rmse"],
            }
        )
    return rows


def run_direction(fit_name: str, records: dict, anchor: dict, args) -> dict:
    fit, other_name = records[fit_name], next(n for n in TESTS if n != fit_name)
    other = records[other_name]
    common.log(
        f"diagnosing {fit_name} ({fit.num_samples} samples), validating on "
        f"{other_name} ({other.num_samples} samples)"
    )
    policy = None
    if args.min_heldout_gain is not None:
        policy = dataclasses.replace(
            jh.families.DamperFamily().default_policy(),
            min_heldout_gain=args.min_heldout_gain,
        )
    start = time.perf_counter()
    diagnosis = jh.diagnose(
        fit,
        key=jax.random.key(args.seed),
        family=jh.families.DamperFamily(),
        policy=policy,
        progress=args.progress,
    )
    seconds = time.perf_counter() - start
    summary = diagnosis.to_dict()
    steps = []
    for step in diagnosis.steps:
        if step.model is None:
            raise RuntimeError(f"diagnosis step {step.label!r} carries no model")
        steps.append(
            {
                **step.to_dict(),
                "fit": spencer_errors(fit, jh.predict(step.model, fit)),
                "validation": spencer_errors(other, jh.predict(step.model, other)),
            }
        )
    final_val = steps[-1]["validation"]
    anchor_val = anchor[other_name]
    verdict = "below" if final_val["rmse"] < anchor_val["rmse"] else "not below"
    common.log(
        f"{fit_name} -> {other_name}: named {', '.join(diagnosis.effects) or 'none'} "
        f"in {seconds:.0f} s; validation RMSE {steps[0]['validation']['rmse']:.1f} -> "
        f"{final_val['rmse']:.1f} N ({verdict} Spencer's published "
        f"{anchor_val['rmse']:.1f} N)"
    )
    return {
        "fit": fit_name,
        "validation": other_name,
        "seconds": seconds,
        "effects": list(diagnosis.effects),
        "steps": steps,
        "finding_gains": finding_gains(steps, list(diagnosis.effects)),
        "screened": common.screened(summary),
        "findings": summary["findings"],
        "unexplained": summary["unexplained"],
        "ambiguities": summary["ambiguities"],
        "final_parameters": summary["final"]["parameters"],
        "final_below_published_on_validation": final_val["rmse"] < anchor_val["rmse"],
        "_models": (diagnosis.steps[0].model, diagnosis.final_model),
    }


def draw_loops(writer, direction: dict, records: dict, spencer) -> None:
    other = records[direction["validation"]]
    window = other.segment(
        float(other.t[0]), float(other.t[0]) + min(LOOP_SECONDS, other.duration)
    )
    x = np.asarray(window.u)
    velocity = np.gradient(x, window.dt)
    base, final = direction["_models"]
    curves = [
        ("measured", np.asarray(window.y), dict(color="0.6", lw=1.6)),
        ("Spencer 1997 (published)", jh.predict(spencer, window), dict(lw=0.9)),
        ("base (fixed field)", jh.predict(base, window), dict(lw=0.9)),
        ("diagnosed", jh.predict(final, window), dict(lw=0.9)),
    ]
    figure, axes = writer.new(2, 7.0, width=7.0)
    for label, force, style in curves:
        axes[0].plot(velocity, force, label=label, **style)
        axes[1].plot(x, force, label=label, **style)
    axes[0].set(xlabel="velocity [cm/s]", ylabel="force [N]")
    axes[1].set(xlabel="displacement [cm]", ylabel="force [N]")
    axes[0].set_title(
        f"fitted on {direction['fit']}, shown on {direction['validation']} "
        f"(first {window.duration:.1f} s)"
    )
    axes[0].legend(fontsize=7)
    writer.save(figure, f"loops_fit_{direction['fit']}.png")


def print_tables(anchor: dict, directions: list[dict]) -> None:
    print()
    print("Spencer et al. (1997) published parameters, simulated:")
    for name, e in anchor.items():
        print(
            f"  {name:<10} RMSE {e['rmse']:7.1f} N  NRMSD {e['nrmsd']:.3f}  E_t "
            f"{e['E_t']:.3f}  E_x {e['E_x']:.3f}  E_xdot {e['E_xdot']:.3f}"
        )
    for d in directions:
        print()
        print(
            f"fitted on {d['fit']} ({d['seconds']:.0f} s), validated on {d['validation']}:"
        )
        print(
            f"  {'step':<52} {'fit RMSE':>9} {'held-out':>9} {'valid. RMSE':>11} "
            f"{'E_t':>6} {'E_x':>6} {'E_xdot':>6}"
        )
        for s in d["steps"]:
            v = s["validation"]
            print(
                f"  {s['step'][:52]:<52} {s['fit']['rmse']:9.1f} "
                f"{s['heldout_rmse']:9.1f} {v['rmse']:11.1f} {v['E_t']:6.3f} "
                f"{v['E_x']:6.3f} {v['E_xdot']:6.3f}"
            )
        for g in d["finding_gains"]:
            print(
                f"  finding {g['effect']:<17} validation RMSE "
                f"{g['validation_rmse_before']:.1f} -> {g['validation_rmse_after']:.1f} "
                f"N ({g['validation_gain']:+.1%})"
            )
        for c in d["screened"]:
            if c["significant"] and not c["accepted"]:
                why = (
                    c["rejected"]
                    if c["heldout_rmse_after"] is None
                    else f"held-out {c['heldout_rmse_before']:.1f} -> "
                    f"{c['heldout_rmse_after']:.1f}"
                )
                print(
                    f"  round {c['round']}: {c['effect']} significant but not "
                    f"adopted ({why})"
                )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    common.add_record_options(
        parser, "mr_damper_dyke_nees/*_converted.csv", "jaxhyst-out/mr_damper"
    )
    common.add_force(parser)
    parser.add_argument(
        "--fit",
        choices=TESTS,
        action="append",
        help="the record(s) to fit on (default: both, one direction each)",
    )
    parser.add_argument(
        "--seconds",
        type=float,
        default=None,
        help="use only the first SECONDS of each record (a smoke run)",
    )
    parser.add_argument(
        "--min-heldout-gain",
        type=float,
        default=None,
        help="the adoption policy's minimum held-out gain (default: the damper "
        "family's, 0.05)",
    )
    parser.add_argument("--progress", action="store_true", help="diagnosis progress")
    args = parser.parse_args(argv)
    if args.seconds is not None and args.seconds <= 0:
        parser.error("--seconds must be positive")
    fits = tuple(dict.fromkeys(args.fit or TESTS))
    names = [] if args.no_figures else [f"loops_fit_{n}.png" for n in fits]
    common.output_paths(args.json, args.out, names, force=args.force)
    args.data_dir = common.open_data(args)
    common.print_machine(common.machine_info())

    records = {name: load(name, args) for name in TESTS}
    spencer = jh.SpencerDamper.spencer_1997()
    anchor = {
        name: spencer_errors(rec, jh.predict(spencer, rec))
        for name, rec in records.items()
    }
    directions = [run_direction(name, records, anchor, args) for name in fits]
    print_tables(anchor, directions)
    if not args.no_figures:
        writer = common.FigureWriter(args.out)
        for d in directions:
            draw_loops(writer, d, records, spencer)
        for path in writer.written:
            print(f"wrote {path}")
    common.write_results(
        args.json,
        config={
            "seconds": args.seconds,
            "seed": args.seed,
            "min_heldout_gain": args.min_heldout_gain,
            "samples": {n: r.num_samples for n, r in records.items()},
        },
        published_spencer_1997=anchor,
        directions=[
            {k: v for k, v in d.items() if not k.startswith("_")} for d in directions
        ],
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
