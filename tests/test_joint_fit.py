"""Fits over several recordings at once, and the status of polish and fit results."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxhyst as jh


TRUTH = jh.PiezoBoucWen(2.0e-6, 0.6, 1.0 / 80.0, 0.02, -0.006, 1.2)
TEMPLATE = jh.PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5)
RATE = 200.0


def _sine_record(frequency, amplitude, periods, *, seed, name, noise=1e-3):
    t = np.arange(int(periods * RATE / frequency) + 1) / RATE
    u = amplitude * 0.5 * (1 - np.cos(2 * np.pi * frequency * t))
    y = np.asarray(jh.simulate(TRUTH, jh.InputPath(0.0, 1 / RATE, u)))
    sigma = noise * np.max(np.abs(y))
    y = y + sigma * np.random.default_rng(seed).standard_normal(y.size)
    return jh.Recording(t, u, y, name=name), sigma


def _problem(recording, space, weights=None):
    return jh.identification.Problem(
        space, recording.input_path(), jnp.asarray(recording.y), jh.RK4(), weights
    )


def test_stacked_problem_is_the_sum_of_its_records():
    # Different lengths: the shorter record is padded and masked, so the stacked
    # sum of squares is exactly the records' own sums.
    a, _ = _sine_record(1.0, 80.0, 2, seed=0, name="a")
    b, _ = _sine_record(2.5, 50.0, 3, seed=1, name="b")
    space = jh.ParameterSpace.default(TEMPLATE, jh.identification.joint_scales([a, b]))
    z = space.from_model(TRUTH.replace(A1=space.template.A1)) + 0.01
    weights_b = jnp.asarray(np.random.default_rng(2).uniform(0, 1, b.num_samples))
    pa, pb = _problem(a, space), _problem(b, space, weights_b)
    stacked = jh.identification.stack_problems([pa, pb])
    assert stacked.measured.shape == (2, max(a.num_samples, b.num_samples))

    def squares(problem, n):
        return float(problem.rmse(z)) ** 2 * n

    total = squares(pa, a.num_samples) + squares(pb, float(jnp.sum(weights_b**2)))
    count = a.num_samples + float(jnp.sum(weights_b**2))
    np.testing.assert_allclose(float(stacked.rmse(z)) ** 2 * count, total, rtol=1e-10)
    # Residuals: both records' residuals in the largest output's unit, padding zero.
    scale = float(stacked.output_scale)
    r = np.asarray(stacked.residuals(z)).reshape(2, -1)
    own_a = np.asarray(pa.residuals(z)) * float(pa.output_scale) / scale
    np.testing.assert_allclose(r[0, : a.num_samples], own_a, rtol=1e-10, atol=1e-14)
    assert b.num_samples < a.num_samples  # b is the padded one
    np.testing.assert_array_equal(r[1, b.num_samples :], 0.0)


def test_joint_fit_recovers_the_model_and_reports_each_recording():
    a, sigma_a = _sine_record(1.0, 80.0, 2, seed=0, name="slow")
    b, sigma_b = _sine_record(2.5, 50.0, 3, seed=1, name="fast")
    fit = jh.identify(
        TEMPLATE,
        [a, b],
        key=jax.random.key(0),
        swarm=jh.MPSO(num_particles=48, num_iterations=120),
    )
    assert jh.status_name(fit.result) == "successful"
    assert [m.recording for m in fit.per_recording] == ["slow", "fast"]
    assert isinstance(fit.predicted, tuple)
    assert [p.shape for p in fit.predicted] == [(a.num_samples,), (b.num_samples,)]
    for m, sigma in zip(fit.per_recording, (sigma_a, sigma_b)):
        assert m.metrics["rmse"] < 1.2 * sigma
    both = np.concatenate([a.y, b.y])
    np.testing.assert_allclose(
        fit.metrics["rmse"],
        jh.metrics.rmse(both, np.concatenate(fit.predicted)),
        rtol=1e-12,
    )
    data = fit.to_dict()
    assert data["status"] == "successful"
    assert [m["recording"] for m in data["metrics"]["per_recording"]] == [
        "slow",
        "fast",
    ]
    one = fit.for_recording(1)
    assert one.metrics == fit.per_recording[1].metrics
    assert one.predicted.shape == (b.num_samples,)
    # One recording keeps the single-record shape of a Fit.
    single = jh.identify(
        TEMPLATE, a, key=jax.random.key(0), swarm=None, start=fit.model
    )
    assert single.per_recording == () and not isinstance(single.predicted, tuple)
    assert "per_recording" not in single.to_dict()["metrics"]


def test_joint_fit_bad_inputs():
    a, _ = _sine_record(1.0, 80.0, 2, seed=0, name="a")
    with pytest.raises(ValueError, match="no recordings"):
        jh.identify(TEMPLATE, [], key=jax.random.key(0))
    with pytest.raises(TypeError, match="recording 1 is a"):
        jh.identify(TEMPLATE, [a, a.y], key=jax.random.key(0))  # type: ignore[list-item]
    with pytest.raises(ValueError, match="one weight array per recording"):
        jh.identify(TEMPLATE, [a, a], key=jax.random.key(0), weights=[None])


def test_polish_and_fit_statuses():
    a, _ = _sine_record(1.0, 80.0, 2, seed=0, name="a")
    space = jh.ParameterSpace.default(TEMPLATE, a)
    problem = _problem(a, space)
    start = space.from_model(TRUTH.replace(A1=space.template.A1)) + 0.05
    # Two steps of a noise-free-tight LM cannot converge: max_steps_reached.
    short = jh.LevenbergMarquardtPolish(max_steps=2, min_gain=1e-15).run(problem, start)
    assert jh.status_name(short.result) == "max_steps_reached"
    assert not short.converged and short.steps == 2
    done = jh.LevenbergMarquardtPolish().run(problem, start)
    assert jh.status_name(done.result) == "successful" and done.converged
    assert done.loss_history[-1] <= done.loss_history[0]
    with pytest.raises(RuntimeError, match="identify: max_steps_reached"):
        jh.identify(
            TEMPLATE,
            a,
            key=jax.random.key(0),
            swarm=None,
            start=TEMPLATE.replace(k1=1e-7),
            polish=jh.LevenbergMarquardtPolish(max_steps=5),
        )
    fit = jh.identify(
        TEMPLATE,
        a,
        key=jax.random.key(0),
        swarm=None,
        start=TEMPLATE.replace(k1=1e-7),
        polish=jh.LevenbergMarquardtPolish(max_steps=5),
        throw=False,
    )
    assert fit.to_dict()["status"] == "max_steps_reached"
    assert fit.to_dict()["polish"]["status"] == "max_steps_reached"
    # A start where the model diverges: nonfinite.
    bad = jnp.full(space.dimension, jnp.nan)
    assert jh.status_name(jh.LevenbergMarquardtPolish().run(problem, bad).result) == (
        "nonfinite"
    )


def test_polish_keeps_its_state_and_compiles_once():
    # The LM loop runs in one compiled program: a second polish of the same
    # structure from another start does not compile again.
    a, _ = _sine_record(1.0, 80.0, 2, seed=0, name="a")
    space = jh.ParameterSpace.default(TEMPLATE, a)
    problem = _problem(a, space)
    polish = jh.LevenbergMarquardtPolish(max_steps=20)
    polish.run(problem, space.from_model(TRUTH.replace(A1=space.template.A1)) + 0.05)
    with jax.log_compiles():
        import logging

        records = []

        class _Catch(logging.Handler):
            def emit(self, record):
                records.append(record.getMessage())

        logger = logging.getLogger("jax")
        handler = _Catch()
        logger.addHandler(handler)
        try:
            polish.run(
                problem, space.from_model(TRUTH.replace(A1=space.template.A1)) - 0.03
            )
        finally:
            logger.removeHandler(handler)
    assert not [m for m in records if "Compiling" in m and "_optimistix_loop" in m]


def test_diagnose_refuses_a_diverged_base_fit(monkeypatch):
    # The base fit's status reaches the diagnosis: a non-finite base fit is an
    # error naming the recording, not a diagnosis of garbage.
    import jaxhyst._diagnose._diagnose as engine

    a, _ = _sine_record(1.0, 80.0, 4, seed=0, name="stage_test")
    real_identify = engine.identify

    def diverged(*args, **kwargs):
        fit = real_identify(*args, **{**kwargs, "swarm": None, "start": TEMPLATE})
        return fit.__class__(
            fit.model,
            fit.predicted,
            fit.metrics,
            fit.swarm,
            fit.polish,
            fit.identifiability,
            fit.timing,
            jh.RESULTS.nonfinite,
        )

    monkeypatch.setattr(engine, "identify", diverged)
    with pytest.raises(ValueError, match="'stage_test' diverged"):
        jh.diagnose(a, key=jax.random.key(0))
