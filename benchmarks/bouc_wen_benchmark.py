"""The Bouc-Wen hysteresis benchmark (Noel & Schoukens 2016), identified with jaxhyst.

The system is the benchmark's force-driven oscillator with a Bouc-Wen restoring force
(`jh.HystereticOscillator`: mass, damping, stiffness, alpha, beta*gamma, beta*delta;
nu fixed at 1, where beta, gamma and delta enter only as the two products). The data
are synthetic: 750 Hz, force [N] -> displacement [m].

1. Identification, from the TRAINING record only (dynoNet's train.h5: five periods of
   a 5-150 Hz random-phase multisine, 8192 samples each, with 8e-6 m output noise).
   The first period holds the start-up transient and is dropped; the other four are
   averaged (for a model in steady state this has the same least-squares minimiser
   as fitting all four, at a quarter of the simulation cost, and their spread gives
   the noise). `jh.periodic.fit_periodic` then runs
   - MPSO (64 particles, up to 150 iterations) in a log-scaled box set by the data's
     scales (`jh.ParameterSpace.default`), on the first 2 s of the period after a 1 s
     warm-up, input cubic-interpolated at 750 Hz, RK4 with 2 substeps;
   - Levenberg-Marquardt on the whole period at that resolution;
   - Levenberg-Marquardt on the whole period with the input upsampled x4 by FFT
     (band-limited) interpolation, cubic between those samples, RK4 with 2 substeps
     (6 kHz steps), after a 2 s warm-up;
   and the identifiability analysis (singular values, standard errors, correlations)
   at the result. `fit_seconds` is the wall time of the first fit in this process,
   compilation included; with `--repeats 2` (default) a second fit gives the
   compiled time.
2. Test, on the official noiseless test sets: multisine, two preceding periods of the
   periodic test input simulated from rest and the last (steady-state) period scored,
   with the x4 band-limited input; sine sweep from rest, its samples cubic-interpolated
   at 750 Hz, RK4 with 20 substeps. The same simulators run with the true parameters
   give the floor that integrator/decimation differences from the official generator
   (Newmark at 15 kHz, FIR decimation) leave.
3. Diagnosis: `jh.diagnose` (which starts from the quasi-static piezo model) on one
   steady-state training period (`--diagnosis-periods`), timed.

    python benchmarks/bouc_wen_benchmark.py
    python benchmarks/bouc_wen_benchmark.py --json bw.json --out jaxhyst-out/bw
    python benchmarks/bouc_wen_benchmark.py --diagnosis-periods 0   # skip step 3
"""

import argparse
import sys
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)

import _common as common  # noqa: E402
import equinox as eqx  # noqa: E402
import numpy as np  # noqa: E402

import jaxhyst as jh  # noqa: E402


PERIOD = 8192  # samples per multisine period
RATE = 750.0
# Test-set simulation RMSE [m] on the multisine, as collected in
# shared/data/bouc_wen_benchmark/README.md (no sine-sweep numbers were found).
PUBLISHED = (
    ("gr-SS-NN (Schoukens, ECC 2021)", 7.53e-6),
    ("SS-NN, improved init (Schoukens, ECC 2021)", 8.91e-6),
    ("PNLSS (Fakhrizadeh Esfahani et al., MSSP 2018)", 1.34e-5),
    ("dynoNet (Forgione & Piga 2021)", 4.52e-5),
)
BAR = {"multisine": 1e-6, "sinesweep": 5e-6}


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    common.add_record_options(
        parser, "bouc_wen_benchmark/", "jaxhyst-out/bouc_wen_benchmark"
    )
    parser.add_argument(
        "--repeats",
        type=int,
        default=2,
        help="fits to run (the first includes compilation; default 2)",
    )
    parser.add_argument(
        "--diagnosis-periods",
        type=int,
        default=1,
        help="steady-state training periods given to jh.diagnose (0 skips it)",
    )
    return parser.parse_args(argv)


def load(data_dir):
    try:
        return jh.datasets.load_bouc_wen_benchmark(data_dir=data_dir)
    except (FileNotFoundError, ImportError) as error:
        raise SystemExit(
            f"bouc_wen_benchmark: cannot load the benchmark data.\n{error}"
        ) from None


def rmse(a, b) -> float:
    return float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)))


_simulate = eqx.filter_jit(jh.simulate)


# --------------------------------------------------------------------------- steps


def identify(bench, seed: int, repeats: int):
    """Fold the training record and fit `repeats` times (the first run compiles);
    returns (fit, average, space, seconds per run: swarm start to fitted model)."""
    average = jh.periodic.average_periods(bench.train, PERIOD, skip=1)
    template = jh.HystereticOscillator(1.0, 1.0, 1.0, 1.0, 1.0, 1.0, nu=1.0)
    space = jh.ParameterSpace.default(template, average.recording)
    seconds, fit = [], None
    for run in range(max(1, repeats)):
        fit = jh.periodic.fit_periodic(
            template,
            average.recording,
            key=jax.random.key(seed),
            space=space,
            noise_sigma=average.mean_sigma,
        )
        seconds.append(fit.timing["fit_s"])
        common.log(
            f"  fit {run + 1}/{repeats}: {fit.timing['fit_s']:.1f} s "
            f"(swarm {fit.timing.get('swarm_s', 0):.1f}, "
            f"LM coarse {fit.timing.get('prepolish_s', 0):.1f}, "
            f"LM fine {fit.timing.get('polish_s', 0):.1f}; identifiability "
            f"{fit.timing.get('identifiability_s', 0):.1f})"
        )
    return fit, average, space, seconds


def multisine_output(model, u, periods_before: int = 2, upsample: int = 4):
    simulation = jh.periodic.PeriodicSimulation(
        warmup=periods_before * PERIOD / RATE,
        upsample=upsample,
        solver=jh.RK4(substeps=2),
    )
    return simulation(model, u, 1 / RATE)


def sweep_output(model, recording, interpolation=None, substeps: int = 20):
    path = recording.input_path(interpolation=interpolation or jh.CubicInterpolation())
    return np.asarray(_simulate(model, path, jh.RK4(substeps=substeps)))


def train_from_rest(model, train, upsample: int = 4):
    """The whole training record simulated from rest (the input repeats exactly, so
    the record is one period of a band-limited periodic signal)."""
    fine = jh.periodic.bandlimited_upsample(train.u, upsample)
    path = jh.InputPath(
        0.0,
        train.dt / upsample,
        np.concatenate([fine, fine[:1]]),
        interpolation=jh.CubicInterpolation(),
    )
    return np.asarray(_simulate(model, path, jh.RK4(substeps=2)))[:-1:upsample]


def evaluate(model, bench) -> dict:
    ms = bench.test_multisine
    sw = bench.test_sinesweep
    y_ms = multisine_output(model, ms.u)
    y_ms_1 = multisine_output(model, ms.u, periods_before=1)
    y_sw = sweep_output(model, sw)
    return {
        "multisine": rmse(y_ms, ms.y),
        "multisine_one_period_before": rmse(y_ms_1, ms.y),
        "sinesweep": rmse(y_sw, sw.y),
        "y_multisine": y_ms,
        "y_sinesweep": y_sw,
    }


def floors(bench) -> dict:
    """The true parameters through the same simulators, and through cruder ones."""
    truth = jh.HystereticOscillator.benchmark_truth()
    ms = bench.test_multisine
    sw = bench.test_sinesweep
    linear_path = jh.InputPath(
        0.0, 1 / RATE, np.concatenate([np.tile(ms.u, 3), ms.u[:1]])
    )
    linear = np.asarray(_simulate(truth, linear_path, jh.RK4(substeps=20)))
    cubic = jh.periodic.PeriodicSimulation(
        warmup=2 * PERIOD / RATE, upsample=1, solver=jh.RK4(substeps=20)
    )(truth, ms.u, 1 / RATE)
    return {
        "multisine": rmse(multisine_output(truth, ms.u), ms.y),
        "multisine_linear_750Hz_rk4x20": rmse(linear[-PERIOD - 1 : -1], ms.y),
        "multisine_cubic_750Hz_rk4x20": rmse(cubic, ms.y),
        "sinesweep": rmse(sweep_output(truth, sw), sw.y),
        "sinesweep_linear_750Hz_rk4x20": rmse(
            sweep_output(truth, sw, jh.LinearInterpolation()), sw.y
        ),
    }


def diagnosis(bench, periods: int, seed: int) -> dict:
    """`jh.diagnose` on `periods` steady-state training periods (from the second)."""
    train = bench.train
    stop = PERIOD * (1 + periods)
    segment = jh.Recording(
        train.t[PERIOD:stop],
        train.u[PERIOD:stop],
        train.y[PERIOD:stop],
        name=f"bouc_wen_train_periods_2_to_{1 + periods}",
        input_name="force",
        output_name="displacement",
        input_unit="N",
        output_unit="m",
    )
    return common.diagnose(segment, seed)


# ------------------------------------------------------------------------- figures


def figures(out: Path, bench, fit, evaluation, truth_sweep, diag) -> list[str]:
    writer = common.FigureWriter(out)
    new, save = writer.new, writer.save
    um = 1e6
    ms = bench.test_multisine
    figure, (top, bottom) = new(2, 6.0)
    window = ms.t < 2.0
    top.plot(ms.t[window], ms.y[window] * um, label="test data")
    top.plot(
        ms.t[window],
        evaluation["y_multisine"][window] * um,
        "--",
        label="identified model",
    )
    top.set_ylabel("displacement [um]")
    top.set_title("Multisine test set (steady state), first 2 s")
    top.legend(loc="upper right")
    bottom.plot(ms.t, (evaluation["y_multisine"] - ms.y) * um, linewidth=0.6)
    bottom.set_xlabel("time [s]")
    bottom.set_ylabel("model - data [um]")
    bottom.set_title(f"error over the period: RMSE {evaluation['multisine']:.3g} m")
    for axis in (top, bottom):
        axis.grid(alpha=0.3)
    save(figure, "multisine_test.png")

    sw = bench.test_sinesweep
    figure, (axis,) = new(1, 4.0)
    axis.plot(
        sw.t,
        (evaluation["y_sinesweep"] - sw.y) * um,
        linewidth=0.4,
        label=f"identified model (RMSE {evaluation['sinesweep']:.3g} m)",
    )
    axis.plot(
        sw.t,
        (truth_sweep - sw.y) * um,
        linewidth=0.4,
        alpha=0.7,
        label=f"true parameters (RMSE {rmse(truth_sweep, sw.y):.3g} m)",
    )
    axis.set_xlabel("time [s] (18 -> 52 Hz)")
    axis.set_ylabel("model - data [um]")
    axis.set_title("Sine-sweep test set, from rest")
    axis.legend(loc="upper right", fontsize="small")
    axis.grid(alpha=0.3)
    save(figure, "sinesweep_error.png")

    # The identified restoring force z against y over the multisine test period.
    simulation = jh.periodic.PeriodicSimulation(warmup=2 * PERIOD / RATE)
    path = simulation.path(ms.u, 1 / RATE)
    _, states = _simulate(fit.model, path, simulation.solver, return_state=True)
    first = int(simulation.scored(path, PERIOD)[0])
    states = np.asarray(states)[first:]  # the scored period on the fine grid
    figure, (axis,) = new(1, 5.0)
    axis.plot(states[:, 0] * um, states[:, 2], linewidth=0.4)
    axis.set_xlabel("displacement y [um]")
    axis.set_ylabel("hysteretic force z [N]")
    axis.set_title("Identified hysteresis: z against y over the multisine test")
    axis.grid(alpha=0.3)
    save(figure, "hysteresis_loop.png")

    if diag is not None:
        segment = diag["recording"]
        result = diag["result"]
        figure, (top, bottom) = new(2, 6.0)
        window = segment.t < segment.t[0] + 1.0
        t = segment.t[window]
        top.plot(t, segment.y[window] * um, label="training data")
        top.plot(
            t,
            np.asarray(result.base_predicted)[window] * um,
            "--",
            label=f"piezo (quasi-static), RMSE {diag['baseline']['rmse']:.3g} m",
        )
        label = "+".join(["piezo", *diag["effects"]])
        top.plot(
            t,
            np.asarray(result.final_predicted)[window] * um,
            ":",
            label=f"{label}, RMSE {diag['final']['rmse']:.3g} m",
        )
        top.set_ylabel("displacement [um]")
        top.set_title("jh.diagnose on the training data (first second shown)")
        top.legend(loc="upper right", fontsize="small")
        bottom.plot(
            segment.t,
            (segment.y - np.asarray(result.base_predicted)) * um,
            linewidth=0.4,
            label="piezo",
        )
        bottom.plot(
            segment.t,
            (segment.y - np.asarray(result.final_predicted)) * um,
            linewidth=0.4,
            label=label,
        )
        bottom.set_xlabel("time [s]")
        bottom.set_ylabel("residual [um]")
        bottom.legend(loc="upper right", fontsize="small")
        for axis in (top, bottom):
            axis.grid(alpha=0.3)
        save(figure, "diagnosis.png")
    return writer.written


# ---------------------------------------------------------------------------- main


def main(argv=None) -> int:
    args = parse_args(argv)
    bench = load(common.open_data(args))

    common.log("identifying from the training record ...")
    fit, average, space, seconds = identify(bench, args.seed, args.repeats)
    model = fit.model
    params = {k: float(v) for k, v in model.parameters().items()}
    report = fit.identifiability
    train_sim = train_from_rest(model, bench.train)
    per_period = [
        rmse(
            train_sim[k * PERIOD : (k + 1) * PERIOD],
            bench.train.y[k * PERIOD :][:PERIOD],
        )
        for k in range(bench.train.num_samples // PERIOD)
    ]

    common.log("evaluating on the test sets ...")
    evaluation = evaluate(model, bench)
    floor = floors(bench)
    truth_sweep = sweep_output(
        jh.HystereticOscillator.benchmark_truth(), bench.test_sinesweep
    )

    diag = None
    if args.diagnosis_periods > 0:
        common.log(f"diagnosing {args.diagnosis_periods} training period(s) ...")
        diag = diagnosis(bench, args.diagnosis_periods, args.seed)

    truth = jh.HystereticOscillator.benchmark_truth().parameters()
    print()
    print("Bouc-Wen benchmark (Noel & Schoukens 2016), jaxhyst")
    print(
        f"training: periods 2-5 of train.h5 averaged ({average.periods} periods; "
        f"noise {average.noise_sigma:.3g} m per sample, {average.mean_sigma:.3g} m "
        "in the average)"
    )
    print(
        f"fit: {seconds[0]:.1f} s first run (compilation included)"
        + (f", {min(seconds[1:]):.1f} s compiled" if len(seconds) > 1 else "")
        + f"; swarm {fit.swarm.iterations_run} iterations"
        f" ({fit.swarm.stop_reason}), final LM {fit.polish.steps} steps; "
        f"training RMSE {fit.metrics['rmse']:.3g} m on the averaged period"
    )
    print(
        "training record from rest, RMSE per period: "
        + ", ".join(f"{v:.3g}" for v in per_period)
        + " m"
    )
    print()
    print(f"{'parameter':<12} {'identified':>14} {'std. error':>11} {'true':>12}")
    for name in model.parameter_names:
        se = report.standard_errors.get(name, float("nan")) if report else float("nan")
        print(
            f"{name:<12} {params[name]:>14.6g} "
            f"{'fixed' if name not in space.names else f'{se:.2g}':>11} "
            f"{float(truth[name]):>12.6g}"
        )
    if report is not None:
        free = list(report.free_names)
        corr = np.asarray(report.correlations)
        off = np.abs(corr - np.eye(len(free)))
        i, j = np.unravel_index(np.nanargmax(off), off.shape)
        print(
            "identifiability: relative singular values "
            + ", ".join(f"{v:.2g}" for v in report.singular_values)
            + f"; largest correlation {corr[i, j]:+.3f} ({free[i]}, {free[j]}); "
            + (
                "no unidentifiable direction"
                if not report.unidentifiable
                else f"unidentifiable: {report.unidentifiable}"
            )
        )
    print(
        "  (with nu = 1 the z-equation depends on beta only through beta*gamma and "
        "beta*delta: beta, gamma, delta are not separately identifiable, so the "
        "model is parameterised by the products)"
    )
    print()
    print(f"{'test-set simulation RMSE [m]':<52} {'multisine':>10} {'sine sweep':>11}")
    print(
        f"{'jaxhyst: identified oscillator (this run)':<52} "
        f"{evaluation['multisine']:>10.3g} {evaluation['sinesweep']:>11.3g}"
    )
    print(
        f"{'jaxhyst: true parameters, same simulators':<52} "
        f"{floor['multisine']:>10.3g} {floor['sinesweep']:>11.3g}"
    )
    print(
        f"{'  true parameters, cubic 750 Hz, RK4 x20':<52} "
        f"{floor['multisine_cubic_750Hz_rk4x20']:>10.3g} {floor['sinesweep']:>11.3g}"
    )
    print(
        f"{'  true parameters, linear 750 Hz, RK4 x20':<52} "
        f"{floor['multisine_linear_750Hz_rk4x20']:>10.3g} "
        f"{floor['sinesweep_linear_750Hz_rk4x20']:>11.3g}"
    )
    for name, value in PUBLISHED:
        print(f"{name:<52} {value:>10.3g} {'-':>11}")
    print(
        f"{'bar for this task':<52} {BAR['multisine']:>10.3g} {BAR['sinesweep']:>11.3g}"
    )
    print(
        "(multisine: 2 periods before the scored one; "
        f"1 period before gives {evaluation['multisine_one_period_before']:.3g})"
    )
    if diag is not None:
        print()
        print(
            f"diagnosis (jh.diagnose from the quasi-static piezo model) on "
            f"{diag['samples']} samples: {diag['seconds']:.0f} s; adopted: "
            f"{', '.join(diag['effects']) or 'nothing'}; RMSE "
            f"{diag['baseline']['rmse']:.3g} -> {diag['final']['rmse']:.3g} m"
        )
        for finding in diag["findings"]:
            print(f"  {finding['effect']}: {finding['evidence']}")
            print(f"    parameters: {finding['parameters']}")
        screened = ", ".join(
            f"round {c['round']} {c['effect']} ({c['statistic']:.0f}/{c['dof']}"
            f"{', passed held-out validation' if c['accepted'] else ''})"
            for c in diag["screened"]
            if c["significant"]
        )
        print(f"  significant in the score test (statistic/dof): {screened}")
        for text in diag["ambiguities"]:
            print(f"  ambiguity: {text}")

    written = []
    if not args.no_figures:
        written = figures(Path(args.out), bench, fit, evaluation, truth_sweep, diag)
        print()
        print("figures: " + ", ".join(written))
    info = common.machine_info()
    print()
    common.print_machine(info)

    if args.json:
        result = {
            "multisine_rmse": evaluation["multisine"],
            "sinesweep_rmse": evaluation["sinesweep"],
            "parameters": params,
            "fit_seconds": seconds[0],
            "fit_seconds_compiled": min(seconds[1:]) if len(seconds) > 1 else None,
            "fit_timing": {k: float(v) for k, v in fit.timing.items()},
            "standard_errors": report.standard_errors if report else None,
            "identifiability": report.to_dict() if report else None,
            "true_parameters": {k: float(v) for k, v in truth.items()},
            "true_parameter_rmse": floor,
            "multisine_rmse_one_period_before": evaluation[
                "multisine_one_period_before"
            ],
            "training": {
                "periods_averaged": average.periods,
                "noise_sigma": average.noise_sigma,
                "averaged_period_rmse": fit.metrics["rmse"],
                "from_rest_rmse_per_period": per_period,
            },
            "published_multisine_rmse": dict(PUBLISHED),
            "diagnosis": None if diag is None else common.without_objects(diag),
            "figures": written,
            "machine": info,
        }
        common.write_json(result, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
