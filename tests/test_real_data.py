"""The real data sets: the Bouc-Wen benchmark and the measured piezo actuator.

Tests that read data skip when the shared data directory is absent (set
JAXHYST_DATA_DIR). The periodic-fit helpers are also checked on synthetic signals.
"""

import jax
import numpy as np
import pytest

import jaxhyst as jh


PERIOD = 8192


def _has(name: str) -> bool:
    return (jh.datasets.default_data_dir() / name).is_dir()


needs_benchmark = pytest.mark.skipif(
    not _has("bouc_wen_benchmark"),
    reason="Bouc-Wen benchmark data not available (set JAXHYST_DATA_DIR)",
)
needs_piezo = pytest.mark.skipif(
    not _has("piezo_actuator_smarthysteresis"),
    reason="piezo actuator data not available (set JAXHYST_DATA_DIR)",
)


@pytest.fixture(scope="module")
def benchmark():
    return jh.datasets.load_bouc_wen_benchmark()


def _rmse(a, b) -> float:
    return float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)))


# ------------------------------------------------------- periodic helpers (no data)


def test_bandlimited_upsample_is_exact_for_band_limited_signals():
    n, factor = 64, 4
    t = np.arange(n) / n
    lines = [(1, 0.3), (7, -1.1), (31, 0.2)]  # all below the Nyquist line n/2

    def f(x):
        return sum(a * np.cos(2 * np.pi * k * x + k) for k, a in lines)

    fine = jh.periodic.bandlimited_upsample(f(t), factor)
    assert fine.shape == (n * factor,)
    np.testing.assert_allclose(fine[::factor], f(t), atol=1e-12)
    np.testing.assert_allclose(
        fine, f(np.arange(n * factor) / (n * factor)), atol=1e-12
    )
    with pytest.raises(ValueError, match="factor"):
        jh.periodic.bandlimited_upsample(f(t), 0)


def test_average_periods_and_noise():
    rng = np.random.default_rng(0)
    period, count, sigma = 200, 5, 0.1
    u = np.tile(np.sin(2 * np.pi * np.arange(period) / period), count)
    clean = np.tile(np.cos(2 * np.pi * np.arange(period) / period), count)
    y = clean + sigma * rng.standard_normal(clean.size)
    y[:period] += 5.0  # a "transient" in the first period
    rec = jh.Recording(np.arange(u.size) * 0.01, u, y)
    avg = jh.periodic.average_periods(rec, period, skip=1)
    assert avg.periods == 4 and avg.recording.num_samples == period
    assert avg.noise_sigma == pytest.approx(sigma, rel=0.1)
    assert avg.mean_sigma == pytest.approx(avg.noise_sigma / 2)
    assert _rmse(avg.recording.y, clean[:period]) == pytest.approx(sigma / 2, rel=0.2)
    with pytest.raises(ValueError, match="whole number"):
        jh.periodic.average_periods(rec, 300)
    broken = jh.Recording(rec.t, rec.u + np.arange(u.size) * 1e-3, rec.y)
    with pytest.raises(ValueError, match="not periodic"):
        jh.periodic.average_periods(broken, period)


def test_periodic_simulation_reaches_steady_state():
    """Warm-ups of one and three periods give the same scored period, and it equals
    the last period of a plain simulation over several periods."""
    model = jh.HystereticOscillator.benchmark_truth()
    rate, period = 750.0, 1500
    t = np.arange(period) / rate
    # Periodic over the 2 s window: whole numbers of cycles.
    u = 40 * np.sin(2 * np.pi * 7.5 * t) + 30 * np.sin(2 * np.pi * 31.5 * t + 1.0)
    short = jh.periodic.PeriodicSimulation(warmup=period / rate, upsample=2)
    long = jh.periodic.PeriodicSimulation(warmup=3 * period / rate, upsample=2)
    y_short = short(model, u, 1 / rate)
    y_long = long(model, u, 1 / rate)
    assert y_short.shape == (period,)
    np.testing.assert_allclose(y_short, y_long, atol=1e-12 + 1e-9 * np.ptp(y_long))
    fine = jh.periodic.bandlimited_upsample(u, 2)
    path = jh.InputPath(
        0.0,
        1 / (2 * rate),
        np.concatenate([np.tile(fine, 4), fine[:1]]),
        interpolation=jh.CubicInterpolation(),
    )
    plain = np.asarray(jh.simulate(model, path, jh.RK4(substeps=2)))
    np.testing.assert_allclose(
        plain[-1 - 2 * period : -1 : 2], y_long, atol=1e-9 * np.ptp(y_long)
    )


# ---------------------------------------------------------------- Bouc-Wen benchmark


@needs_benchmark
def test_benchmark_shapes(benchmark):
    assert benchmark.train.num_samples == 5 * PERIOD
    assert benchmark.test_multisine.num_samples == PERIOD
    assert benchmark.test_sinesweep.num_samples == 153000
    for rec in (benchmark.train, benchmark.test_multisine, benchmark.test_sinesweep):
        assert rec.sample_rate == pytest.approx(750.0)
        assert rec.u.shape == rec.y.shape == rec.t.shape
    # The training input repeats exactly, period after period.
    u = benchmark.train.u.reshape(5, PERIOD)
    assert np.array_equal(u, np.broadcast_to(u[0], u.shape))


@needs_benchmark
def test_true_parameters_reproduce_the_multisine_test_set(benchmark):
    """The published parameters, run to steady state, reproduce the official test
    period to within 5e-7 m (measured 2.5e-7 m: the rest is the generator's Newmark
    integration and FIR decimation). A wrong equation fails by orders of magnitude."""
    ms = benchmark.test_multisine
    simulation = jh.periodic.PeriodicSimulation(warmup=2.0, upsample=4)
    truth = jh.HystereticOscillator.benchmark_truth()
    assert _rmse(simulation(truth, ms.u, ms.dt), ms.y) < 5e-7
    wrong = {
        "beta_delta sign": truth.replace(beta_delta=-truth.beta_delta),
        "beta_gamma sign": truth.replace(beta_gamma=-truth.beta_gamma),
        "no hysteretic force": truth.replace(alpha=0.0),
        "nu = 2": truth.replace(nu=2.0),
    }
    for what, model in wrong.items():
        # (diverging to NaN also counts as not reproducing it)
        assert not _rmse(simulation(model, ms.u, ms.dt), ms.y) < 1e-5, what
    # Piecewise-linear input at 750 Hz is not good enough for this benchmark.
    linear = jh.periodic.PeriodicSimulation(
        warmup=2.0,
        upsample=1,
        solver=jh.RK4(substeps=20),
        interpolation=jh.LinearInterpolation(),
    )
    assert _rmse(linear(truth, ms.u, ms.dt), ms.y) > 3e-6


@needs_benchmark
def test_true_parameters_reproduce_the_sine_sweep(benchmark):
    """From rest over 204 s: within 3e-6 m (measured 2.5e-6 m)."""
    sw = benchmark.test_sinesweep
    path = sw.input_path(interpolation=jh.CubicInterpolation())
    truth = jh.HystereticOscillator.benchmark_truth()
    y = jh.simulate(truth, path, jh.RK4(substeps=5))
    assert _rmse(y, sw.y) < 3e-6


@needs_benchmark
def test_training_noise_level(benchmark):
    avg = jh.periodic.average_periods(benchmark.train, PERIOD, skip=1)
    assert avg.periods == 4
    # The benchmark specifies 8e-6 m band-limited output noise.
    assert 6e-6 < avg.noise_sigma < 9e-6
    simulation = jh.periodic.PeriodicSimulation()
    truth = jh.HystereticOscillator.benchmark_truth()
    residual = _rmse(
        simulation(truth, avg.recording.u, avg.recording.dt), avg.recording.y
    )
    assert residual == pytest.approx(avg.mean_sigma, rel=0.1)


@needs_benchmark
@pytest.mark.slow
def test_fit_on_two_training_periods_converges(benchmark):
    """Swarm + LM on the average of training periods 2-3 only recovers the published
    parameters and the multisine test set."""
    train = benchmark.train
    short = jh.Recording(
        train.t[: 3 * PERIOD], train.u[: 3 * PERIOD], train.y[: 3 * PERIOD]
    )
    avg = jh.periodic.average_periods(short, PERIOD, skip=1)
    template = jh.HystereticOscillator(1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0)
    fit = jh.periodic.fit_periodic(
        template,
        avg.recording,
        key=jax.random.key(1),
        space=jh.ParameterSpace.default(template, avg.recording),
        noise_sigma=avg.mean_sigma,
    )
    truth = jh.HystereticOscillator.benchmark_truth().parameters()
    for name, value in fit.model.parameters().items():
        assert float(value) == pytest.approx(float(truth[name]), rel=0.01), name
    assert fit.metrics["rmse"] < 1.2 * avg.mean_sigma
    ms = benchmark.test_multisine
    y = jh.periodic.PeriodicSimulation()(fit.model, ms.u, ms.dt)
    assert _rmse(y, ms.y) < 1e-6
    report = fit.identifiability
    assert not report.unidentifiable
    for name, se in report.standard_errors.items():
        assert abs(float(fit.model.parameters()[name]) - float(truth[name])) < 5 * se


# ------------------------------------------------------------------ measured piezo


@needs_piezo
def test_piezo_shape_and_offset():
    rec = jh.datasets.load_piezo_actuator()
    assert rec.num_samples == 50001
    assert rec.sample_rate == pytest.approx(5000.0)
    step = int(np.argmax(np.abs(np.diff(rec.u)))) + 1
    assert rec.t[step] == pytest.approx(3.2572, abs=1e-3)
    # At 0 V before the switch-on the sensor reads about -1.7 um, not 0.
    assert np.mean(rec.y[:step]) == pytest.approx(-1.68, abs=0.1)
