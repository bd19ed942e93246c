import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import lowered_while, piezo_model

import jaxhyst as jh


def _sine(amplitude, rate=500.0, periods=2):
    t = np.arange(0, periods * 2 * np.pi + 1e-9, 1 / rate)
    return jh.InputPath.from_samples(t, amplitude * np.sin(t))


def _unloading_stiffness_ratio(beta, gamma, n=1.0, amplitude=2.0):
    """Slope dh/du just after the upper reversal, relative to A (= 1): > 1, = 1, < 1
    as beta - gamma is > 0, = 0, < 0 (the loop families of Figure 3)."""
    model = jh.BoucWen(1.0, 0.0, 1.0, 1.0, beta, gamma, n)
    path = _sine(amplitude)
    _, states = jh.simulate(model, path, return_state=True)
    u = np.asarray(path.values)
    h = np.asarray(states[:, 0])
    second = slice(len(u) // 2, None)
    top = len(u) // 2 + int(np.argmax(u[second]))
    k = 25
    return (h[top + k] - h[top]) / (u[top + k] - u[top]), h


@pytest.mark.parametrize(
    "beta, gamma, family",
    [
        (0.6, 0.4, "steep"),  # Fig. 3a
        (0.6, 0.6, "linear"),  # Fig. 3b
        (0.6, -0.6, "steep"),  # Fig. 3c
        (0.4, 0.6, "soft"),  # Fig. 3d
        (0.8, 0.2, "steep"),  # Fig. 3f
        (0.5, 0.5, "linear"),  # Fig. 3f
        (0.4, 0.6, "soft"),  # Fig. 3f
    ],
)
def test_figure3_loop_families(beta, gamma, family):
    ratio, h = _unloading_stiffness_ratio(beta, gamma)
    assert np.all(np.isfinite(h))
    if family == "steep":
        assert ratio > 1.05
    elif family == "linear":
        assert abs(ratio - 1) < 1e-3
    else:
        assert ratio < 0.95
    # The loop encloses area (hysteresis) unless the operator is degenerate.
    assert float(np.ptp(h)) > 0


def test_figure3e_unstable_set_is_rejected():
    # Fig. 3e (A = 1, beta = 0.4, gamma = -0.6): beta + gamma < 0 with beta - gamma > 0
    report = jh.bibo_stability(jh.BoucWen(1.0, 0.5, 1.0, 1.0, 0.4, -0.6, 1.0))
    assert not report.stable and "beta+gamma" in report.reason


STABLE = [
    (1.0, 0.6, 0.4),
    (1.0, 0.6, -0.6 + 1.3),
    (1.0, 0.4, 0.6),
    (1.0, 0.0, 0.6),
    (-1.0, 0.6, 0.4),
    (-1.0, 0.5, -0.8),
]
UNSTABLE = [
    (1.0, -0.2, -0.6),  # A > 0: beta + gamma < 0
    (1.0, -0.4, 0.2),  # A > 0: beta - gamma < 0 with beta < 0
    (-1.0, 0.4, 0.6),  # A < 0: beta - gamma < 0, beta + gamma > 0
    (-1.0, -0.6, -0.8),  # A < 0: beta + gamma < 0 with beta < 0
]


@pytest.mark.parametrize("A, beta, gamma", STABLE)
def test_table2_stable_sets_stay_bounded(A, beta, gamma):
    model = jh.BoucWen(1.0, 0.5, 1.0, A, beta, gamma, 1.5)
    report = jh.bibo_stability(model)
    assert report.stable, report.reason
    assert bool(jh.is_bibo_stable(A, beta, gamma, 1.5))
    bounds = []
    for amplitude in (1.0, 10.0, 100.0):
        _, states = jh.simulate(model, _sine(amplitude, rate=50.0), return_state=True)
        bounds.append(float(jnp.max(jnp.abs(states))))
    assert np.all(np.isfinite(bounds))
    # Bounded input, bounded h: h saturates instead of growing with the amplitude.
    assert bounds[2] < 5 * bounds[1]


@pytest.mark.parametrize("A, beta, gamma", UNSTABLE)
def test_table2_unstable_sets_are_rejected(A, beta, gamma):
    model = jh.BoucWen(1.0, 0.5, 1.0, A, beta, gamma, 1.5)
    report = jh.bibo_stability(model)
    assert not report.stable
    assert "Table 2 needs" in report.reason
    assert not bool(jh.is_bibo_stable(A, beta, gamma, 1.5))


def test_unstable_set_grows_without_bound():
    model = jh.BoucWen(1.0, 0.5, 1.0, 1.0, -0.2, -0.6, 1.5)
    _, states = jh.simulate(
        model, _sine(10.0, rate=50.0), return_state=True, throw=False
    )
    assert not np.all(np.isfinite(states)) or float(jnp.max(jnp.abs(states))) > 1e3


def test_fit_and_diagnosis_reports_say_when_a_model_leaves_table_2():
    from jaxhyst._report._console import fit_summary
    from jaxhyst._stability import stability_json, stability_warning

    unstable = jh.BoucWen(1.0, 0.5, 1.0, 1.0, -0.2, -0.6, 1.5)
    report = jh.bibo_stability(unstable)
    assert stability_json(unstable) == {"stable": False, "reason": report.reason}
    warning = stability_warning(unstable)
    assert warning is not None and "outside Table 2" in warning
    assert report.reason in warning
    stable = jh.BoucWen(1.0, 0.5, 1.0, 1.0, 0.6, 0.4, 1.5)
    assert stability_json(stable) == {
        "stable": True,
        "reason": jh.bibo_stability(stable).reason,
    }
    assert stability_warning(stable) is None
    # In a fit's summary and JSON.
    path = _sine(2.0, rate=50.0)
    recording = jh.Recording(
        np.asarray(path.times), np.asarray(path.values), np.zeros(path.num_samples)
    )
    fit = jh.Fit(unstable, jnp.zeros(path.num_samples), {}, None, None, None, {})
    assert fit.to_dict()["stability"]["stable"] is False
    metrics = dict.fromkeys(("rmse", "mad", "mrd", "mae", "nrmsd"), 0.0)
    fit = eqx.tree_at(lambda f: f.metrics, fit, metrics)
    assert f"stability: {warning}" in fit_summary(fit, recording)


def test_stability_needs_positive_d_and_n_at_least_one():
    assert not jh.bibo_stability(jh.BoucWen(1.0, 0.5, -1.0, 1.0, 0.6, 0.4, 1.0))
    assert not jh.bibo_stability(piezo_model(n=0.5))
    assert jh.bibo_stability(piezo_model())
    # The benchmark oscillator's operator (beta*gamma = 800, beta*delta = -1100) lies
    # outside Table 2's classes: only the structure's stiffness keeps it bounded.
    report = jh.bibo_stability(jh.HystereticOscillator.benchmark_truth())
    assert not report.stable and "beta+gamma=-300" in report.reason


def test_parameters_and_replace():
    model = piezo_model()
    assert list(model.parameters()) == ["k1", "k2", "A1", "beta1", "gamma1", "n"]
    assert float(model.replace(k1=2.0).k1) == 2.0
    assert float(model.k1) == 0.3  # the original is untouched
    corrected = jh.CorrectedPiezoBoucWen.from_piezo(model, phi=0.1)
    assert float(corrected.phi) == pytest.approx(0.1) and float(corrected.eps) == 0


def test_smoothing_rules_are_consistent():
    x = jnp.array([-1.0, -0.3, -1e-3, 0.0, 1e-3, 0.3, 1.0])
    for rule in (jh.ExactSign(), jh.TanhSign(0.1), jh.AlgebraicSign(0.1)):
        np.testing.assert_allclose(rule.abs(x), x * rule.sign(x))
        assert float(rule.abs(0.0)) == 0.0
    np.testing.assert_allclose(jh.TanhSign(1e-6).sign(x[x != 0]), np.sign(x[x != 0]))


@pytest.mark.parametrize(
    "rate, frequency, damping", [(1000.0, 40.0, 0.1), (1000.0, 300.0, 0.05)]
)
def test_extended_stage_hold_matches_finely_integrated_stage(rate, frequency, damping):
    """ExtendedPiezo propagates its stage exactly per sample (first-order hold of the
    static response); PiezoStage integrates the same equations with fine RK4 steps.
    They agree to the hold's O(dt^2) error, even at 0.3 x the sample rate."""
    from helpers import multisine_path

    path = multisine_path(rate=rate, duration=2.0)
    base = piezo_model()
    held = jh.ExtendedPiezo.around(base, path).with_dynamics(frequency, damping)
    stage = jh.PiezoStage.from_piezo(
        base, natural_frequency=frequency, damping_ratio=damping
    )
    a = jh.simulate(held, path)
    b = jh.simulate(stage, path, jh.RK4(substeps=50))
    assert float(jnp.max(jnp.abs(a - b)) / jnp.max(jnp.abs(b))) < 2e-5
    # Not the quasi-static output: the stage really filters.
    quasi_static = jh.simulate(jh.ExtendedPiezo.around(base, path), path)
    assert float(jnp.max(jnp.abs(a - quasi_static)) / jnp.max(jnp.abs(b))) > 1e-3
    with pytest.raises(ValueError, match="only RK4 applies"):
        jh.simulate(held, path, jh.DiffraxSolver())


def test_asking_whether_a_stage_updates_per_sample_compiles_nothing():
    """Refits and the swarm's objective ask `has_sample_update` outside `jit`: for a
    stage it must not build the hold map (its matrix exponential compiled on its
    own took 0.66 s of a warm diagnosis), and it agrees with `sample_update`."""
    from helpers import multisine_path

    path = multisine_path(rate=1000.0, duration=0.5)
    quasi_static = jh.ExtendedPiezo.around(piezo_model(), path)
    stage = quasi_static.with_dynamics(40.0, 0.1)
    answers, lowered = lowered_while(
        lambda: [m.has_sample_update(path) for m in (quasi_static, stage)]
    )
    assert answers == [False, True]
    assert lowered == []
    assert [m.sample_update(path) is not None for m in (quasi_static, stage)] == answers
