import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import lowered_while

import jaxhyst as jh


TRUTH = jh.PiezoBoucWen(k1=0.3, k2=1.0, A1=0.5, beta1=0.6, gamma1=0.2, n=1.5)


def _recording(model=TRUTH, rate=200.0, noise=1e-3, seed=0, signal=None):
    signal = jh.paper_u1() if signal is None else signal
    path = jh.sample(signal, rate)
    y = np.asarray(jh.simulate(model, path))
    sigma = noise * np.max(np.abs(y))
    rng = np.random.default_rng(seed)
    return (
        jh.Recording(
            np.asarray(path.times),
            np.asarray(path.values),
            y + sigma * rng.standard_normal(y.size),
            name="synthetic",
        ),
        sigma,
    )


TEMPLATE = jh.PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5)
FAST = jh.MPSO(num_particles=48, num_iterations=120)


def test_parameter_space_round_trip_and_scaling():
    space = jh.ParameterSpace(
        TEMPLATE,
        {"k1": (-1.0, 1.0), "beta1": (1e-3, 10.0), "n": (1.0, 3.0)},
        log_scale=["beta1"],
    )
    z = jnp.array([0.25, 0.5, 0.75])
    values = space.to_values(z)
    np.testing.assert_allclose(values, [-0.5, 0.1, 2.5], rtol=1e-12)
    np.testing.assert_allclose(space.to_unit(values), z, rtol=1e-12)
    model = space.to_model(z)
    assert float(model.k2) == 1.0  # fixed parameters untouched
    np.testing.assert_allclose(space.from_model(model), z, rtol=1e-12)


def test_a_stable_shape_space_keeps_every_model_in_table_2():
    # Bounds reaching beta < 0 and beta + gamma < 0 (outside Table 2 for A > 0):
    # with stable_shape the models are floored back inside; models already inside
    # are unchanged, and gamma's floor still moves with beta (a polish at the edge
    # keeps a derivative along it).
    for template in (
        jh.BoucWen(1.0, 0.1, 1.0, 1.0, 0.5, 0.3, 1.5),
        jh.StructuralBoucWen(1.0, 0.1, 1.0, 0.5, 0.3, 1.5),
    ):
        bounds = {"beta": (-1.0, 2.0), "gamma": (-3.0, 2.0)}
        plain = jh.ParameterSpace(template, bounds)
        stable = jh.ParameterSpace(template, bounds, stable_shape=True)
        points = jax.random.uniform(jax.random.key(0), (200, 2))
        outside = 0
        for z in points:
            loose, kept = plain.to_model(z), stable.to_model(z)
            outside += not jh.is_bibo_stable(*loose.bouc_wen_shape())
            assert jh.is_bibo_stable(*kept.bouc_wen_shape())
            if jh.is_bibo_stable(*loose.bouc_wen_shape()):
                assert float(kept.beta) == float(loose.beta)
                assert float(kept.gamma) == float(loose.gamma)
        assert outside > 50
        edge = stable.to_unit(jnp.array([0.5, -1.0]))  # beta + gamma < 0
        slope = jax.grad(lambda z, space=stable: space.to_model(z).gamma)(edge)
        assert float(slope[0]) < 0 and float(slope[1]) == 0
    with pytest.raises(TypeError, match="stable_shape"):
        jh.ParameterSpace(TEMPLATE, {"k1": (0.0, 1.0)}, stable_shape="yes")  # pyright: ignore[reportArgumentType]


def test_a_polish_keeps_a_share_within_its_physical_limits():
    # The slip-lock's `pinch` is the share of the hysteretic rate removed near the
    # slip: a polish that steps past the box keeps it in [0, 1], where a larger
    # value would reverse the rate on reloading; the limit has no derivative beyond
    # it, so Levenberg-Marquardt stops at the edge.
    template = jh.StructuralBoucWen(1.0, 0.1, 1.0, 0.5, 0.3, 1.5)
    space = jh.ParameterSpace(template, {"pinch": (0.2, 0.8), "k": (0.5, 2.0)})
    pinch = space.names.index("pinch")
    far = jnp.full(2, 3.0)  # far past both upper bounds
    values = dict(zip(space.names, space.to_values(far).tolist()))
    assert values["pinch"] == 1.0  # held at its ceiling
    assert values["k"] == pytest.approx(5.0)  # no physical ceiling
    assert float(space.to_values(jnp.full(2, -2.0))[pinch]) == 0.0  # its floor
    assert float(jax.grad(lambda z: space.to_model(z).pinch)(far)[pinch]) == 0.0
    inside = jax.grad(lambda z: space.to_model(z).pinch)(jnp.full(2, 0.5))
    assert float(inside[pinch]) == pytest.approx(0.6)


def test_parameter_space_errors():
    with pytest.raises(ValueError, match="not parameters"):
        jh.ParameterSpace(TEMPLATE, {"k9": (0.0, 1.0)})
    with pytest.raises(ValueError, match="lower < upper"):
        jh.ParameterSpace(TEMPLATE, {"k1": (1.0, 0.0)})
    with pytest.raises(ValueError, match="include zero"):
        jh.ParameterSpace(TEMPLATE, {"k1": (-1.0, 1.0)}, log_scale=["k1"])
    with pytest.raises(ValueError, match="constant"):
        jh.ParameterSpace.default(
            TEMPLATE,
            jh.DataScales(
                input_peak=0.0,
                output_peak=1.0,
                input_rms=0.0,
                output_rms=1.0,
                duration=10.0,
                sample_rate=1000.0,
            ),
        )


def test_identify_recovers_truth_to_noise_floor():
    recording, sigma = _recording()
    fit = jh.identify(TEMPLATE, recording, key=jax.random.key(0), swarm=FAST)
    # At the noise floor: the residual is the noise (slightly below: fitted noise).
    assert fit.metrics["rmse"] < 1.02 * sigma
    # The identifiable combinations match the truth: k1, n, and the gauge-invariant
    # k2*A1, beta1*|c|^(n-1)... checked through the noise-free output.
    assert float(fit.model.k1) == pytest.approx(0.3, rel=2e-2)
    assert float(fit.model.n) == pytest.approx(1.5, rel=5e-2)
    path = recording.input_path()
    clean = jh.simulate(TRUTH, path)
    assert float(jnp.sqrt(jnp.mean((fit.predicted - clean) ** 2))) < 0.5 * sigma
    gain = float(fit.model.k2 * fit.model.A1)
    assert gain == pytest.approx(0.5, rel=5e-2)
    # Polish never makes things worse than the swarm.
    assert fit.polish is not None and fit.swarm is not None
    assert fit.polish.loss_history[-1] <= fit.polish.loss_history[0]
    assert fit.metrics["rmse"] <= fit.swarm.best_fitness * 1.0001 + 1e-12


def test_identifiability_reports_the_scaling_symmetry():
    recording, _ = _recording(noise=0.0)
    report = jh.identification.identifiability(
        TRUTH, recording.input_path(), jnp.asarray(recording.y)
    )
    assert len(report.unidentifiable) == 1
    direction = report.unidentifiable[0]
    # h -> c*h: relative changes k2 : A1 : beta1 : gamma1 = -1 : 1 : (1-n) : (1-n)
    ratio = direction["k2"] / direction["A1"]
    assert ratio == pytest.approx(-1.0, rel=1e-4)
    assert direction["beta1"] / direction["A1"] == pytest.approx(1 - 1.5, rel=1e-3)
    assert direction["gamma1"] / direction["A1"] == pytest.approx(1 - 1.5, rel=1e-3)
    assert "k1" not in direction and "n" not in direction
    # The symmetry is exact: moving along it leaves the output unchanged.
    c = 1.7
    moved = TRUTH.replace(
        k2=TRUTH.k2 / c,
        A1=c * TRUTH.A1,
        beta1=TRUTH.beta1 * c ** (1 - 1.5),
        gamma1=TRUTH.gamma1 * c ** (1 - 1.5),
    )
    path = recording.input_path()
    np.testing.assert_allclose(
        jh.simulate(moved, path), jh.simulate(TRUTH, path), atol=1e-10
    )


def test_gauge_fixed_fit_has_finite_standard_errors():
    recording, _ = _recording(seed=3)
    fit = jh.identify(TEMPLATE, recording, key=jax.random.key(1), swarm=FAST)
    report = fit.identifiability
    assert report is not None
    assert "A1" not in report.free_names
    assert all(np.isfinite(v) and v > 0 for v in report.standard_errors.values())
    # Without the gauge, the parameters on the redundant direction (the scaling
    # symmetry k2 : A1 : beta1 : gamma1) have no standard error; k1 and n keep theirs.
    ungauged = jh.identification.identifiability(
        fit.model, recording.input_path(), jnp.asarray(recording.y)
    )
    errors = ungauged.standard_errors
    assert all(np.isnan(errors[n]) for n in ("k2", "A1", "beta1", "gamma1"))
    assert all(np.isfinite(errors[n]) and errors[n] > 0 for n in ("k1", "n"))


SMALL_SWARM = jh.MPSO(num_particles=24, num_iterations=30)


def _problem(recording):
    space = jh.ParameterSpace.default(TEMPLATE, recording)
    return jh.identification.Problem(
        space, recording.input_path(), jnp.asarray(recording.y), jh.RK4()
    )


def _swarm_only(recording):
    # 30 iterations end before the 40-iteration stall rule can be met.
    return jh.identify(
        TEMPLATE,
        recording,
        key=jax.random.key(5),
        swarm=SMALL_SWARM,
        polish=None,
        throw=False,
    )


def test_same_key_same_fit_and_polish_variants():
    recording, _ = _recording(rate=100.0)
    small = SMALL_SWARM
    a, b = _swarm_only(recording), _swarm_only(recording)
    assert a.metrics == b.metrics
    for polish in (jh.BFGSPolish(max_steps=30), jh.AdamPolish(max_steps=100)):
        fit = jh.identify(
            TEMPLATE,
            recording,
            key=jax.random.key(5),
            swarm=small,
            polish=polish,
            throw=False,  # 30 BFGS steps need not converge
        )
        assert fit.polish is not None
        assert fit.metrics["rmse"] <= a.metrics["rmse"] * (1 + 1e-9)


def test_polish_stops_when_a_chunk_stops_paying():
    recording, _ = _recording(rate=100.0)
    swarm_only = _swarm_only(recording)
    problem = _problem(recording)
    z0 = problem.space.from_model(swarm_only.model)
    # Any gain short of 100 % ends the polish after its first chunk of 10 steps.
    eager = jh.LevenbergMarquardtPolish(min_gain=1.0).run(problem, z0)
    assert eager.steps == 10 and eager.converged and len(eager.loss_history) == 2
    # The default stops at 1 % of the RMSE's sampling spread, 0.01/sqrt(2n).
    threshold = max(1e-5, 0.01 / np.sqrt(2 * recording.y.size))
    default = jh.LevenbergMarquardtPolish().run(problem, z0)
    best_before = np.minimum.accumulate(default.loss_history)[:-1]
    gains = 1 - default.loss_history[1:] / best_before
    assert default.converged and default.steps >= 10
    assert np.all(gains[:-1] >= threshold)
    patient = jh.LevenbergMarquardtPolish(min_gain=1e-15).run(problem, z0)
    assert patient.steps >= default.steps
    assert patient.loss_history.min() <= default.loss_history.min()


def test_two_stage_corrected_fit_finds_asymmetry():
    truth = jh.CorrectedPiezoBoucWen.from_piezo(TRUTH, phi=0.0, eps=0.02)
    recording, sigma = _recording(truth)
    base = jh.identify(TEMPLATE, recording, key=jax.random.key(0), swarm=FAST)
    corrected_template = jh.CorrectedPiezoBoucWen.from_piezo(base.model)
    space = jh.ParameterSpace(
        corrected_template, {"phi": (-0.5, 0.5), "eps": (-0.1, 0.1)}
    )
    second = jh.identify(
        corrected_template,
        recording,
        key=jax.random.key(1),
        space=space,
        swarm=jh.MPSO(num_particles=24, num_iterations=60),
    )
    assert second.metrics["rmse"] < base.metrics["rmse"]
    joint = jh.identify(
        corrected_template,
        recording,
        key=jax.random.key(2),
        swarm=None,
        start=second.model,
    )
    assert joint.metrics["rmse"] < 1.05 * sigma


def test_identify_bad_inputs():
    recording, _ = _recording(rate=10.0)
    with pytest.raises(TypeError, match="Recording"):
        jh.identify(TEMPLATE, np.zeros(5), key=jax.random.key(0))  # type: ignore
    with pytest.raises(ValueError, match="start"):
        jh.identify(TEMPLATE, recording, key=jax.random.key(0), swarm=None)
    for stride in (0, -2, 2.5):
        with pytest.raises(ValueError, match="swarm_stride"):
            jh.identify(TEMPLATE, recording, key=jax.random.key(0), swarm_stride=stride)


def test_fit_does_not_retrace_for_new_parameter_values():
    recording, _ = _recording(rate=50.0)
    space = jh.ParameterSpace.default(
        TEMPLATE,
        jh.DataScales(
            input_peak=4.0,
            output_peak=1.0,
            input_rms=4.0,
            output_rms=1.0,
            duration=10.0,
            sample_rate=1000.0,
        ),
    )
    problem = jh.identification.Problem(
        space, recording.input_path(), jnp.asarray(recording.y), jh.RK4()
    )

    @eqx.filter_jit
    @eqx.debug.assert_max_traces(max_traces=1)
    def loss(z, p):
        return p.rmse(z)

    for value in (0.2, 0.5, 0.8):
        loss(jnp.full(space.dimension, value), problem)


def test_standard_errors_match_parameter_scatter_units():
    """Standard errors are in parameter units: scaling the output by 10 scales the
    standard error of k1 (an output/input gain) by 10."""
    recording, _ = _recording(seed=4)
    space_free = ("k1", "k2", "beta1", "gamma1", "n")
    base = jh.identification.identifiability(
        TRUTH, recording.input_path(), jnp.asarray(recording.y), free=space_free
    )
    scaled_truth = TRUTH.replace(k1=10 * TRUTH.k1, k2=10 * TRUTH.k2)
    scaled = jh.identification.identifiability(
        scaled_truth,
        recording.input_path(),
        10 * jnp.asarray(recording.y),
        free=space_free,
    )
    ratio = scaled.standard_errors["k1"] / base.standard_errors["k1"]
    assert ratio == pytest.approx(10.0, rel=1e-3)
    # And of the right size: well below the value, above zero.
    assert 0 < base.standard_errors["k1"] < 1e-2 * float(TRUTH.k1)


def test_swarm_samples_per_step_follows_the_input():
    t = np.arange(10001) / 1000.0
    slow = 2 - 2 * np.cos(0.2 * np.pi * t)  # u1: 1.26e-3 V per sample, 4 V range
    per_step = jh.identification.swarm_samples_per_step
    assert per_step(slow) == 31  # 1 % of the range per step
    assert per_step(slow, input_fraction=0.001) == 5  # budget
    assert per_step(slow, input_fraction=0.001, max_steps=10000) == 3
    assert per_step(slow, min_steps=1000) == 10
    fast = np.sin(2 * np.pi * 50 * t)  # 0.3 of the amplitude per sample
    assert per_step(fast) == 5  # only the 2000-step budget
    assert per_step(fast[:1001]) == 1
    assert per_step(np.zeros(5000)) == 24  # no motion: min_steps
    with pytest.raises(ValueError, match="1-D"):
        jh.identification.swarm_samples_per_step(np.zeros((3, 3)))


def test_swarm_objective_uses_every_sample():
    # The swarm's cheap objective (coarse RK4 steps, dense output) ranks like the
    # full-resolution one and is close to it in value near a good fit.
    from jaxhyst._identification._problem import swarm_problem as _swarm_problem

    recording, _ = _recording(rate=1000.0)
    problem = _problem(recording)
    coarse = _swarm_problem(problem, 5)
    assert coarse.solver == jh.RK4(samples_per_step=5)
    assert coarse.measured.shape == problem.measured.shape
    z = jax.random.uniform(jax.random.key(0), (64, problem.space.dimension))
    fine = np.asarray(jax.vmap(problem.rmse)(z))
    cheap = np.asarray(jax.vmap(coarse.rmse)(z))
    ok = np.isfinite(fine)
    assert np.array_equal(ok, np.isfinite(cheap))
    assert np.array_equal(np.argsort(fine[ok]), np.argsort(cheap[ok]))


def test_polish_residuals_carry_the_forward_mode_jacobian():
    # The polish hands optimistix residuals whose derivative is one batched
    # forward pass (a tangent per coordinate); it must equal the plain derivative,
    # through `jax.linearize` (what Levenberg-Marquardt materialises) and `jvp`.
    from jaxhyst._identification._polish import _residuals_jacfwd
    from jaxhyst._identification._problem import problem_residuals

    recording, _ = _recording(rate=100.0)
    problem = _problem(recording)
    z = 0.9 * problem.space.from_model(TRUTH) + 0.05
    plain = jax.jacfwd(lambda w: problem_residuals(problem, w))(z)
    value, linear = jax.linearize(lambda w: _residuals_jacfwd(w, problem), z)
    np.testing.assert_allclose(value, problem_residuals(problem, z), rtol=1e-12)
    materialised = jax.vmap(linear, out_axes=1)(jnp.eye(z.size))
    np.testing.assert_allclose(materialised, plain, rtol=1e-10, atol=1e-12)
    direction = jnp.linspace(-1.0, 1.0, z.size)
    _, tangent = jax.jvp(lambda w: _residuals_jacfwd(w, problem), (z,), (direction,))
    np.testing.assert_allclose(tangent, plain @ direction, rtol=1e-10, atol=1e-12)
    # Reverse mode transposes the same matrix.
    cotangent = jnp.ones(value.shape)
    (gradient,) = jax.vjp(lambda w: _residuals_jacfwd(w, problem), z)[1](cotangent)
    np.testing.assert_allclose(gradient, plain.T @ cotangent, rtol=1e-10, atol=1e-12)


def test_polishes_of_one_problem_with_other_step_counts_share_one_program():
    # A diagnosis polishes one model for a candidate's, the converging and the
    # final number of steps: the number of steps is a value of the compiled loop,
    # not part of the program.
    recording, _ = _recording(rate=100.0)
    problem = _problem(recording)
    z0 = problem.space.from_model(TEMPLATE)
    first = jh.LevenbergMarquardtPolish(max_steps=20, min_gain=1e-12)
    assert first.run(problem, z0).steps <= 20

    def polish_with_other_step_counts():
        for steps in (30, 40, 70):
            polish = jh.LevenbergMarquardtPolish(max_steps=steps, min_gain=1e-12)
            result = polish.run(problem, z0)
            assert result.steps <= steps
            assert len(result.loss_history) <= -(-steps // polish.window) + 1

    _, lowered = lowered_while(polish_with_other_step_counts)
    assert not [name for name in lowered if "_optimistix_loop" in name]


def test_the_polish_program_scores_with_one_call_of_the_loss(monkeypatch):
    # The start and every window are scored by one call site: a second one
    # compiled the whole simulation again (0.4 s of the polish's 1 s compile).
    from jaxhyst._identification import _polish

    recording, _ = _recording(rate=100.0)
    problem = _problem(recording)
    polish = jh.LevenbergMarquardtPolish()
    z0 = problem.space.from_model(TEMPLATE)
    calls = []
    scored = _polish.problem_rmse

    def counted(*args):
        calls.append(1)
        return scored(*args)

    monkeypatch.setattr(_polish, "problem_rmse", counted)
    eqx.filter_make_jaxpr(_polish._optimistix_loop.__wrapped__)(
        *polish._loop_arguments(problem, z0)
    )
    assert len(calls) == 1
    monkeypatch.undo()
    result = polish.run(problem, z0)
    assert result.loss_history[0] == pytest.approx(
        float(_polish.problem_rmse(problem, z0)), rel=1e-12
    )
