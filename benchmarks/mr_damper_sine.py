"""Benchmark: the MR damper family on measured sine tests without a recorded command.

The Labcontrol shaking-table tests (`jh.datasets.load_mr_damper_sine`; UTFPR, MIT
licence): displacement [mm] -> force [N] at 100 Hz, one sine each (0.8-1.2 Hz, 11-25 mm).
The series "ensaio1.1" ... "ensaio10.1" ran one after another with the table's
amplitude stepped down and its frequency up; the damper's setting is not in the
log, and nothing suggests it changed within the series, so the tests are treated
as one damper at one field: the command is added as a constant
(`rec.with_input("command", 0.0, unit="V")`, an unknown level).

1. Diagnoses `--fit` tests together
   (`jh.diagnose([...], family=jh.families.DamperFamily())`: one model, each test simulated from rest, held-out blocks in each).
2. Simulates every step's model on the `--validate` tests (not fitted) and reports
   each step's RMSE there.
3. Says what sine tests at one field cannot separate: the diagnosis's
   `cannot_show` (field dependence and driver lag need a varying command), its
   ambiguities, and the significant candidates it could not adopt.

    python benchmarks/mr_damper_sine.py
    python benchmarks/mr_damper_sine.py --fit ensaio1.1 ensaio5.1 --validate ensaio3.1
"""

import argparse
import sys
import time

import jax
import numpy as np


jax.config.update("jax_enable_x64", True)

import _common as common  # noqa: E402

import jaxhyst as jh  # noqa: E402


FIT = ("ensaio1.1", "ensaio4.1", "ensaio7.1")
VALIDATE = ("ensaio2.1", "ensaio5.1", "ensaio9.1")


def load(name: str, data_dir) -> jh.Recording:
    return jh.datasets.load_mr_damper_sine(name, data_dir=data_dir).with_input(
        "command", 0.0, unit="V"
    )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    common.add_data_dir(parser, "mr_damper_labcontrol_utfpr/*.mat")
    parser.add_argument("--fit", nargs="+", default=list(FIT), help="tests to fit")
    parser.add_argument(
        "--validate", nargs="+", default=list(VALIDATE), help="tests to validate on"
    )
    parser.add_argument("--seed", type=int, default=0, help="diagnosis seed")
    parser.add_argument("--progress", action="store_true", help="diagnosis progress")
    common.add_json(parser)
    common.add_force(parser)
    args = parser.parse_args(argv)
    if set(args.fit) & set(args.validate):
        parser.error("a test cannot be in both --fit and --validate")
    common.output_paths(args.json, force=args.force)
    folder = common.data_dir(args.data_dir)
    common.print_machine(common.machine_info())

    fit = [load(name, folder) for name in args.fit]
    held = [load(name, folder) for name in args.validate]
    start = time.perf_counter()
    diagnosis = jh.diagnose(
        fit,
        key=jax.random.key(args.seed),
        family=jh.families.DamperFamily(),
        progress=args.progress,
    )
    seconds = time.perf_counter() - start

    steps = []
    for step in diagnosis.steps:
        if step.model is None:
            raise RuntimeError(f"diagnosis step {step.label!r} carries no model")
        errors = [
            float(np.sqrt(np.mean((np.asarray(r.y) - jh.predict(step.model, r)) ** 2)))
            for r in held
        ]
        steps.append(
            {**step.to_dict(), "validation_rmse": dict(zip(args.validate, errors))}
        )
    summary = diagnosis.to_dict()
    print()
    print(
        f"fitted on {', '.join(args.fit)} together ({seconds:.0f} s); named: "
        f"{', '.join(diagnosis.effects) or 'nothing'}"
    )
    print(f"  {'step':<50} {'fit RMSE':>9} {'held-out':>9}  validation RMSE [N]")
    for s in steps:
        valid = "  ".join(f"{n} {v:.1f}" for n, v in s["validation_rmse"].items())
        print(
            f"  {s['step'][:50]:<50} {s['rmse']:9.1f} {s['heldout_rmse']:9.1f}  {valid}"
        )
    print("what these tests cannot separate:")
    for item in diagnosis.cannot_show:
        print(f"  - {item.effect}: {item.reason}")
    for statement in summary["ambiguities"]:
        print(f"  - {statement}")
    for c in common.screened(summary):
        if c["significant"] and not c["accepted"]:
            print(
                f"  - round {c['round']}: {c['effect']} is significant but was not "
                f"adopted: {c['rejected']}"
            )
    for item in diagnosis.unexplained:
        print(f"  - unexplained: {item.description}; resembles {item.resembles}")
    common.write_results(
        args.json,
        fit=args.fit,
        validate=args.validate,
        seconds=seconds,
        effects=list(diagnosis.effects),
        steps=steps,
        cannot_show=summary["cannot_show"],
        ambiguities=summary["ambiguities"],
        screened=common.screened(summary),
        unexplained=summary["unexplained"],
        per_recording=summary.get("per_recording", []),
        final_parameters=summary["final"]["parameters"],
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
