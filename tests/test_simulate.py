import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import lowered_while, multisine_path, paper_u1_path, piezo_model

import jaxhyst as jh


REFERENCE = jh.DiffraxSolver(rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("make_path", [paper_u1_path, multisine_path])
@pytest.mark.parametrize(
    "model",
    [
        piezo_model(),
        piezo_model(n=1.0, beta1=0.9, gamma1=-0.3),
        jh.BoucWen(2.0, 0.4, 1.5, 1.0, 0.6, -0.6, 2.0),
    ],
)
def test_scan_rk4_agrees_with_diffrax(make_path, model):
    path = make_path()
    y_rk4 = jh.simulate(model, path)
    y_ref = jh.simulate(model, path, REFERENCE)
    scale = float(jnp.max(jnp.abs(y_ref)))
    # Measured at 1 kHz: <= 6e-7 of the output range (u1: ~2e-10; the multisine
    # crosses h = 0 often, where |h|^n is not smooth for n < 2 with the exact sign).
    assert float(jnp.max(jnp.abs(y_rk4 - y_ref))) < 1e-6 * scale


def test_stage_rk4_agrees_with_diffrax():
    model = jh.PiezoStage.from_piezo(
        piezo_model(), natural_frequency=20.0, damping_ratio=0.05
    )
    path = multisine_path()
    y_rk4 = jh.simulate(model, path, jh.RK4(substeps=4))
    y_ref = jh.simulate(model, path, REFERENCE)
    assert float(jnp.max(jnp.abs(y_rk4 - y_ref))) < 1e-7 * float(
        jnp.max(jnp.abs(y_ref))
    )


def _convergence_order(model, path, substeps=(1, 2, 4, 8)):
    reference = jh.simulate(model, path, jh.RK4(substeps=128))
    errors = [
        float(
            jnp.max(jnp.abs(jh.simulate(model, path, jh.RK4(substeps=m)) - reference))
        )
        for m in substeps
    ]
    steps = [float(path.dt) / m for m in substeps]
    slope, _ = np.polyfit(np.log(steps), np.log(errors), 1)
    return slope


def test_rk4_convergence_order_is_four():
    # Coarse sampling (5 Hz) so the error is far above round-off; a smooth sign makes
    # the vector field smooth, as the order theory requires.
    t = np.arange(0, 10.0 + 1e-9, 0.2)
    path = jh.InputPath.from_samples(t, 2 - 2 * np.cos(0.2 * np.pi * t))
    model = piezo_model(n=2.0, smoothing=jh.TanhSign(0.2))
    order = _convergence_order(model, path, substeps=(2, 4, 8, 16))
    assert 3.6 < order < 4.4, order


def test_stage_convergence_order_is_four():
    t = np.arange(0, 4.0 + 1e-9, 0.05)
    u = np.sin(2 * np.pi * 0.5 * t)
    path = jh.InputPath.from_samples(t, u)
    model = jh.PiezoStage.from_piezo(
        piezo_model(n=2.0, smoothing=jh.TanhSign(0.05)),
        natural_frequency=3.0,
        damping_ratio=0.2,
    )
    order = _convergence_order(model, path)
    assert 3.6 < order < 4.4, order


def test_coarse_steps_converge_at_fourth_order():
    # Steps spanning k samples of a ramp (its linear interpolation is exact, so no
    # rate kink sits inside a step) with a smooth sign: the dense output is 4th-order
    # like the step, so the error falls as k^4 (measured 4.03).
    t = np.arange(0, 4.0 + 1e-9, 0.002)
    path = jh.InputPath.from_samples(t, 1.5 * t)
    model = piezo_model(n=2.0, smoothing=jh.TanhSign(0.2))
    reference = jh.simulate(model, path)
    ks = (5, 10, 20, 40)
    errors = [
        float(
            jnp.max(
                jnp.abs(
                    jh.simulate(model, path, jh.RK4(samples_per_step=k)) - reference
                )
            )
        )
        for k in ks
    ]
    order, _ = np.polyfit(np.log(ks), np.log(errors), 1)
    assert 3.6 < order < 4.4, (order, errors)


@pytest.mark.parametrize("k", [2, 3, 7, 8])
def test_coarse_steps_agree_with_sample_steps(k):
    # Piecewise-linear input (rate kinks inside every coarse step) and the exact sign.
    # u1 at 1 kHz, whose reversal falls on a step's node (k = 2, 8) or midpoint:
    # measured <= 2e-7 of the output range. The multisine reverses inside steps,
    # where RK4 drops to first order locally: measured 2e-5 (k = 2) to 3e-4 (k = 8).
    # Neither record's length is a multiple of 3 or 7.
    model = piezo_model()
    for path, tolerance in ((paper_u1_path(), 1e-6), (multisine_path(), 1e-3)):
        y = jh.simulate(model, path)
        y_k = jh.simulate(model, path, jh.RK4(samples_per_step=k))
        assert y_k.shape == y.shape
        assert float(jnp.max(jnp.abs(y_k - y))) < tolerance * float(jnp.max(jnp.abs(y)))


def test_coarse_steps_bad_arguments():
    with pytest.raises(ValueError, match="samples_per_step"):
        jh.RK4(samples_per_step=0)
    with pytest.raises(ValueError, match="choose one"):
        jh.RK4(substeps=2, samples_per_step=3)
    path = paper_u1_path(rate=100.0)
    stage = jh.ExtendedPiezo.around(piezo_model(), path).with_dynamics(5.0, 0.3)
    assert stage.sample_update(path) is not None
    with pytest.raises(ValueError, match="sample_update"):
        jh.simulate(stage, path, jh.RK4(samples_per_step=2))


def test_corrected_model_with_zero_corrections_is_the_piezo_model():
    base = piezo_model()
    path = paper_u1_path()
    corrected = jh.CorrectedPiezoBoucWen.from_piezo(base)
    np.testing.assert_allclose(
        jh.simulate(base, path), jh.simulate(corrected, path), rtol=0, atol=1e-14
    )


def test_corrected_model_effects():
    base = piezo_model()
    path = paper_u1_path(periods=2)
    y0 = jh.simulate(base, path)
    y_eps = jh.simulate(jh.CorrectedPiezoBoucWen.from_piezo(base, eps=0.02), path)
    y_phi = jh.simulate(jh.CorrectedPiezoBoucWen.from_piezo(base, phi=0.3), path)
    assert float(jnp.max(jnp.abs(y_eps - y0))) > 1e-2
    assert float(jnp.max(jnp.abs(y_phi - y0))) > 1e-2
    # Against diffrax (coarser: the shifted input has kinks inside RK4 steps).
    corrected = jh.CorrectedPiezoBoucWen.from_piezo(base, phi=0.1, eps=0.01)
    diff = jh.simulate(corrected, path) - jh.simulate(corrected, path, REFERENCE)
    assert float(jnp.max(jnp.abs(diff))) < 1e-4


def test_stage_nests_the_quasi_static_model():
    base = piezo_model()
    path = paper_u1_path()
    stage = jh.PiezoStage.from_piezo(base, natural_frequency=1e3, damping_ratio=0.7)
    diff = jh.simulate(stage, path, jh.RK4(substeps=8)) - jh.simulate(base, path)
    # The remaining lag is ~ (2*zeta/omega) * ydot ~ 2e-4.
    assert float(jnp.max(jnp.abs(diff))) < 5e-4


def test_stage_from_physical_constants():
    stage = jh.PiezoStage.from_physical(
        m=0.1, c=2.0, ks=1e4, k=2e4, alpha=0.5, D=2.0, A=1.0, beta=0.6, gamma=0.2, n=1
    )
    assert np.isclose(float(stage.natural_frequency), np.sqrt(1e5) / (2 * np.pi))
    assert np.isclose(float(stage.damping_ratio), 2.0 / (2 * np.sqrt(1e3)))
    assert np.isclose(float(stage.k1), 1.0) and np.isclose(float(stage.k2), 2.0)
    assert np.isclose(float(stage.A1), 0.5)


def test_rate_independence():
    """Playing the same input three times slower leaves the y-u loop unchanged."""
    model = jh.BoucWen(1.0, 0.3, 1.0, 1.0, 0.5, 0.1, 1.5)
    rate = 1000.0
    t_fast = np.arange(0, 4.0 + 1e-9, 1 / rate)
    t_slow = np.arange(0, 12.0 + 1e-9, 1 / rate)
    shape = lambda s: np.sin(2 * np.pi * s) + 0.4 * np.sin(6 * np.pi * s + 0.5)
    y_fast = jh.simulate(model, jh.InputPath.from_samples(t_fast, shape(t_fast / 4)))
    y_slow = jh.simulate(model, jh.InputPath.from_samples(t_slow, shape(t_slow / 12)))
    # Up to where linear interpolation cuts the turning points (<= 1e-6 here).
    np.testing.assert_allclose(y_slow[::3], y_fast, rtol=0, atol=2e-6)
    # A rate-dependent system (the stage) would not pass the same check.
    stage = jh.PiezoStage.from_piezo(
        piezo_model(), natural_frequency=2.0, damping_ratio=0.3
    )
    s_fast = jh.simulate(stage, jh.InputPath.from_samples(t_fast, shape(t_fast / 4)))
    s_slow = jh.simulate(stage, jh.InputPath.from_samples(t_slow, shape(t_slow / 12)))
    assert float(jnp.max(jnp.abs(s_slow[::3] - s_fast))) > 1e-2


def test_float32_and_float64():
    path64 = paper_u1_path()
    path32 = jh.InputPath(path64.t0, path64.dt, path64.values.astype(jnp.float32))
    y64 = jh.simulate(piezo_model(), path64)
    y32 = jh.simulate(piezo_model(), path32)
    assert y64.dtype == jnp.float64 and y32.dtype == jnp.float32
    np.testing.assert_allclose(np.asarray(y32), np.asarray(y64), atol=1e-4)


def test_jit_vmap_over_parameters_and_inputs():
    path = paper_u1_path(rate=200.0)
    models = jax.vmap(lambda b: piezo_model(beta1=b))(jnp.array([0.3, 0.6, 0.9]))
    ys = jax.jit(jax.vmap(jh.simulate, in_axes=(0, None)))(models, path)
    for i, b in enumerate([0.3, 0.6, 0.9]):
        np.testing.assert_allclose(ys[i], jh.simulate(piezo_model(beta1=b), path))
    paths = jax.vmap(lambda a: jh.InputPath(path.t0, path.dt, a * path.values))(
        jnp.array([0.5, 1.0])
    )
    ys = jax.vmap(jh.simulate, in_axes=(None, 0))(piezo_model(), paths)
    np.testing.assert_allclose(ys[1], jh.simulate(piezo_model(), path))


def test_no_recompilation_when_parameter_values_change():
    path = paper_u1_path(rate=100.0)

    @eqx.filter_jit
    @eqx.debug.assert_max_traces(max_traces=1)
    def run(model, inputs):
        return jh.simulate(model, inputs)

    for beta in (0.3, 0.6, 0.9):
        run(piezo_model(beta1=beta, n=1.0 + beta), path)


@pytest.mark.parametrize("smoothing", [jh.TanhSign(1e-3), jh.AlgebraicSign(1e-3)])
def test_gradients_match_finite_differences(smoothing):
    path = paper_u1_path(rate=200.0)
    target = jh.simulate(piezo_model(), path)
    names = ("k1", "k2", "A1", "beta1", "gamma1", "n")
    x0 = jnp.array([0.28, 1.1, 0.45, 0.65, 0.15, 1.6])

    def loss(x):
        model = piezo_model(smoothing=smoothing, **dict(zip(names, x)))
        return jnp.mean((jh.simulate(model, path) - target) ** 2)

    grad = jax.grad(loss)(x0)
    step = 1e-6
    fd = jnp.array(
        [
            (loss(x0.at[i].add(step)) - loss(x0.at[i].add(-step))) / (2 * step)
            for i in range(6)
        ]
    )
    np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-9)
    # Forward mode agrees with reverse mode.
    np.testing.assert_allclose(jax.jacfwd(loss)(x0), grad, rtol=1e-8)


@pytest.mark.parametrize("n", [1.0, 1.5, 2.0, 3.0])
@pytest.mark.parametrize("smoothing", [jh.ExactSign(), jh.TanhSign(1e-2)])
def test_gradient_finite_at_h_zero(n, smoothing):
    model = piezo_model(n=n, smoothing=smoothing)
    drive = jh.Drive(jnp.array(1.0), jnp.array(0.5))

    def rate(h, exponent):
        return model.replace(n=exponent).vector_field(0.0, jnp.array([h]), drive)[0]

    dh, dn = jax.grad(rate, argnums=(0, 1))(0.0, n)
    assert np.isfinite(dh) and np.isfinite(dn)
    # d/dh of |h|^n at 0 is 0 for n > 1; for n == 1 the exact kink gives the
    # one-sided value that matches sign(0) = 0.
    assert float(dn) == 0.0
    # And through a whole simulation that starts at h = 0:
    path = paper_u1_path(rate=50.0)
    g = jax.grad(lambda e: jnp.sum(jh.simulate(model.replace(n=e), path)))(n)
    assert np.isfinite(g)


def test_simulate_runs_without_jit():
    # Op by op, every RK4 step is dozens of dispatches: a short path (a loading
    # and an unloading branch) keeps it to seconds.
    path = paper_u1_path(rate=2.0)
    with jax.disable_jit():
        y = jh.simulate(piezo_model(), path)
    np.testing.assert_allclose(y, jh.simulate(piezo_model(), path), atol=1e-12)


def test_divergence_raises_with_advice():
    path = paper_u1_path(rate=100.0)
    unstable = piezo_model(A1=1.0, beta1=-5.0, gamma1=-5.0, n=2.0)
    with pytest.raises(Exception, match="non-finite output"):
        jh.simulate(unstable, path)
    y = jh.simulate(unstable, path, throw=False)
    assert not bool(jnp.all(jnp.isfinite(y)))


def test_bad_arguments():
    path = paper_u1_path(rate=10.0)
    with pytest.raises(TypeError, match="InputPath"):
        jh.simulate(piezo_model(), np.zeros(10))  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="jaxhyst model"):
        jh.simulate("piezo", path)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="substeps"):
        jh.RK4(substeps=0)
    with pytest.raises(ValueError, match="initial_state"):
        jh.simulate(piezo_model(), path, initial_state=jnp.zeros(3))
    with pytest.raises(ValueError, match="width"):
        jh.TanhSign(0.0)
    with pytest.raises(ValueError, match="unknown parameter"):
        piezo_model().replace(k3=1.0)
    with pytest.raises(ValueError, match="uniformly"):
        jh.InputPath.from_samples(np.array([0.0, 1.0, 3.0]), np.zeros(3))


def test_input_bias_gradient_matches_sample_scale_differences():
    """d/dphi sees the input's curvature (smoothed over samples), so a gradient-based
    fit can move the input bias; it matches differences taken over one sample."""
    path = paper_u1_path(rate=100.0)
    base = piezo_model()

    def loss(phi):
        model = jh.CorrectedPiezoBoucWen.from_piezo(base, phi=phi)
        return jnp.sum(jh.simulate(model, path) ** 2)

    step = float(path.dt)
    fd = (loss(0.2 + step) - loss(0.2 - step)) / (2 * step)
    np.testing.assert_allclose(jax.grad(loss)(0.2), fd, rtol=1e-3)
    assert abs(float(jax.grad(loss)(0.0))) > 0


@pytest.mark.parametrize(
    "model, solver",
    [
        (piezo_model(), jh.RK4()),
        (piezo_model(), jh.RK4(substeps=3)),
        (piezo_model(), jh.RK4(samples_per_step=3)),
        (piezo_model(), jh.RK4(samples_per_step=7)),
        (
            jh.PiezoStage.from_piezo(
                piezo_model(), natural_frequency=40.0, damping_ratio=0.2
            ),
            jh.RK4(substeps=2),
        ),
        (piezo_model(), jh.DiffraxSolver()),
    ],
)
def test_sum_squared_error_matches_simulate(model, solver):
    path = multisine_path(rate=200.0, duration=2.0)
    measured = jh.simulate(piezo_model(k2=0.9), path) + 0.01
    weights = jnp.asarray(np.random.default_rng(0).uniform(0, 2, path.num_samples))
    predicted = jh.simulate(model, path, solver)
    for w in (None, weights):
        expected = jnp.sum(((1.0 if w is None else w) * (predicted - measured)) ** 2)
        got = jh.metrics.sum_squared_error(model, path, measured, solver, weights=w)
        np.testing.assert_allclose(got, expected, rtol=1e-10)


def test_sum_squared_error_bad_arguments():
    path = multisine_path(rate=200.0, duration=1.0)
    with pytest.raises(ValueError, match="measured must have shape"):
        jh.metrics.sum_squared_error(piezo_model(), path, jnp.zeros(3))
    with pytest.raises(TypeError, match="sum_squared_error: model"):
        jh.metrics.sum_squared_error("piezo", path, jnp.zeros(path.num_samples))


def test_a_simulation_and_its_jacobian_trace_the_vector_field_and_the_power_once(
    monkeypatch,
):
    # The four stages of an RK4 step share one nested program, and so do their
    # derivatives and batches; |h|^n (a hundred operations of polynomial) is one
    # program too. Inline, each was traced again at every stage (4 times a step,
    # and again under the Jacobian's forward mode).
    import jaxhyst._smoothing as smoothing

    counts = {"vector_field": 0, "power": 0}
    vector_field, power = jh.PiezoBoucWen.vector_field, smoothing.positive_pow

    def counted_vector_field(self, t, state, drive):
        counts["vector_field"] += 1
        return vector_field(self, t, state, drive)

    def counted_power(base, exponent):
        counts["power"] += 1
        return power(base, exponent)

    monkeypatch.setattr(jh.PiezoBoucWen, "vector_field", counted_vector_field)
    monkeypatch.setattr(smoothing, "positive_pow", counted_power)
    # A length no other test simulates: nothing of it is traced yet.
    path = jh.InputPath.from_samples(np.arange(37) / 100.0, np.sin(np.arange(37) / 5))

    def output(k):
        return jh.simulate(piezo_model(k1=k[0], n=k[1]), path, jh.RK4(substeps=2))

    jax.make_jaxpr(jax.jacfwd(output))(jnp.array([0.3, 1.5]))
    assert counts["vector_field"] == 1
    assert counts["power"] <= 1


def test_an_eager_simulation_compiles_one_program_and_new_values_none():
    # Called outside jit, `simulate` and `sum_squared_error` are one program each (op
    # by op, the drive at every sample, the outputs and the checks lowered some
    # forty small programs per record length); new parameter values reuse them.
    # A length no other test simulates: nothing of it is compiled yet.
    t = np.arange(41) / 100.0
    path = jh.InputPath.from_samples(t, np.sin(t * 20))
    model, moved = piezo_model(), piezo_model(k1=0.5)

    def calls():
        y = jh.simulate(model, path)
        jh.metrics.sum_squared_error(model, path, y)
        y2 = jh.simulate(moved, path)
        jh.metrics.sum_squared_error(moved, path, y)
        return y, y2

    (y, y2), lowered = lowered_while(calls)
    assert lowered == ["jit(simulate)", "jit(sum_squared_error)"]
    assert not np.array_equal(y, y2)
