"""One model from several recordings: what a joint fit over two or three excitation
frequencies determines that one frequency leaves loose.

A piezo stage with dynamics (`PiezoStage`, eq. 3-4: a mass-spring-damper driven by
the hysteresis, natural frequency f_n, damping ratio zeta) is recorded under
paper-like raised-cosine sines, 0-4 V as `paper_u1`, at a low frequency and at faster ones.
Far below f_n the stage only delays the output by about 2*zeta/omega_n: one slow
record pins that ratio but hardly f_n and zeta apart. Faster records add the
(f/f_n)^2 magnitude term that separates them. Each fit is a full `identify`
(swarm + polish, no knowledge of the truth); the identifiability report at each fit
gives the standard errors and the weakest direction.

    python benchmarks/joint_fit.py [--json OUT] [--data-seed 0]
"""

import argparse
import time

import _common as common
import jax
import numpy as np

import jaxhyst as jh


jax.config.update("jax_enable_x64", True)

RATE = 2000.0
TRUTH = jh.PiezoStage.from_piezo(
    jh.PiezoBoucWen.paper_table4(3), natural_frequency=120.0, damping_ratio=0.4
)
TEMPLATE = jh.PiezoStage.from_piezo(
    jh.PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5),
    natural_frequency=50.0,
    damping_ratio=0.5,
)
SOLVER = jh.RK4(substeps=4)


def record(frequency: float, *, seed: int, periods: int = 3, noise: float = 0.002):
    """A raised-cosine sine 0-4 V at `frequency`, `periods` periods, the stage's
    output with white noise of `noise` times its peak."""
    t = np.arange(int(round(periods * RATE / frequency)) + 1) / RATE
    u = 2.0 * (1 - np.cos(2 * np.pi * frequency * t))
    y = np.asarray(jh.simulate(TRUTH, jh.InputPath(0.0, 1 / RATE, u), SOLVER))
    sigma = noise * float(np.max(np.abs(y)))
    rng = np.random.default_rng([seed, int(frequency * 1000)])
    noisy = y + sigma * rng.standard_normal(y.size)
    return jh.Recording(
        t, u, noisy, name=f"sine_{frequency:g}Hz", input_unit="V", output_unit="m"
    )


def summarise(fit: jh.Fit) -> dict:
    stage = fit.model
    if not isinstance(stage, jh.PiezoStage):
        raise TypeError(f"joint_fit: expected a PiezoStage fit, got {type(stage)}.")
    report = fit.identifiability
    assert report is not None
    errors = report.standard_errors
    relative = {
        name: errors[name] / abs(float(getattr(fit.model, name)))
        for name in ("natural_frequency", "damping_ratio")
    }
    i = report.free_names.index("natural_frequency")
    j = report.free_names.index("damping_ratio")
    return {
        "status": jh.status_name(fit.result),
        "correlation_fn_zeta": float(report.correlations[i, j]),
        "rmse": fit.metrics["rmse"],
        "per_recording": [m.to_dict() for m in fit.per_recording],
        "natural_frequency": float(stage.natural_frequency),
        "damping_ratio": float(stage.damping_ratio),
        "relative_standard_error": relative,
        "smallest_relative_singular_value": float(report.singular_values[-1]),
        "seconds": fit.timing["total_s"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    common.add_json(parser)
    parser.add_argument("--data-seed", type=int, default=0)
    parser.add_argument(
        "--frequencies",
        default="5,40,80",
        help="the records' frequencies in Hz, slowest first",
    )
    args = parser.parse_args()
    frequencies = [float(f) for f in args.frequencies.split(",")]
    records = [record(f, seed=args.data_seed) for f in frequencies]
    results = {}
    for count in range(1, len(records) + 1):
        chosen = records[:count]
        label = " + ".join(r.name for r in chosen)
        start = time.perf_counter()
        fit = jh.identify(
            TEMPLATE,
            chosen if count > 1 else chosen[0],
            key=jax.random.key(0),
            solver=SOLVER,
            throw=False,
        )
        row = summarise(fit)
        results[label] = row
        se = row["relative_standard_error"]
        print(
            f"{label}: {row['status']}, RMSE {row['rmse']:.3g} m; f_n "
            f"{row['natural_frequency']:.4g} Hz (truth 120) ± "
            f"{100 * se['natural_frequency']:.3g} %, zeta {row['damping_ratio']:.4g} "
            f"(truth 0.4) ± {100 * se['damping_ratio']:.3g} %, correlation "
            f"{row['correlation_fn_zeta']:+.4f}; "
            f"{time.perf_counter() - start:.1f} s",
            flush=True,
        )
    truth = {k: float(v) for k, v in TRUTH.parameters().items()}
    common.write_results(
        args.json, truth=truth, frequencies_hz=frequencies, results=results
    )


if __name__ == "__main__":
    main()
