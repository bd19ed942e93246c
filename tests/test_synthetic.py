import jax
import numpy as np
import pytest

import jaxhyst as jh
from jaxhyst._synthetic import EFFECTS


DURATION, RATE = 8.0, 500.0


def _case(effects, seed=0, **kwargs):
    kwargs = {"duration": DURATION, "rate": RATE, **kwargs}
    return jh.concealed_recording(effects, key=jax.random.key(seed), **kwargs)


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


@pytest.fixture(scope="module")
def clean():
    return _case((), seed=3)


def test_rich_excitation_is_a_piezo_drive():
    path = jh.rich_excitation(jax.random.key(1), duration=DURATION, rate=RATE)
    u = np.asarray(path.values)
    assert path.num_samples == round(DURATION * RATE) + 1
    assert float(path.dt) == pytest.approx(1 / RATE)
    assert u.min() >= -1e-9 and u.max() <= 100.0 + 1e-9
    assert np.ptp(u) > 30.0  # large swings, not only small wiggles
    assert u[0] == 0.0  # starts at rest
    # Continuous: no jump larger than the fastest segment's slope allows.
    assert np.max(np.abs(np.diff(u))) < 0.1 * 100.0
    # Holds: the last 0.5 s is a plateau.
    assert np.ptp(u[-round(0.5 * RATE) :]) == 0.0


def test_rich_excitation_depends_on_the_key_only():
    a = jh.rich_excitation(jax.random.key(4), duration=DURATION, rate=RATE)
    b = jh.rich_excitation(jax.random.key(4), duration=DURATION, rate=RATE)
    c = jh.rich_excitation(jax.random.key(5), duration=DURATION, rate=RATE)
    np.testing.assert_array_equal(a.values, b.values)
    assert not np.allclose(a.values, c.values)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_base_truth_is_a_stable_paper_like_model(seed):
    model = jh.base_truth(jax.random.key(seed))
    assert jh.bibo_stability(model)
    p = {k: float(v) for k, v in model.parameters().items()}
    assert 1.0 <= p["n"] <= 2.5
    assert p["A1"] < 0 < p["k2"] and p["k1"] > 0
    # 0..100 V gives roughly 0..100 um.
    path = jh.sample(jh.RaisedCosine(50.0, 0.5, duration=2.0), 200.0)
    y = np.asarray(jh.simulate(model, path))
    assert 80.0 < y.max() < 115.0


def test_determinism_per_key():
    a = _case(("creep",), seed=7, noise="coloured")
    b = _case(("creep",), seed=7, noise="coloured")
    c = _case(("creep",), seed=8, noise="coloured")
    np.testing.assert_array_equal(a.recording.y, b.recording.y)
    np.testing.assert_array_equal(a.recording.u, b.recording.u)
    assert a.sizes == b.sizes and a.truth_description == b.truth_description
    assert not np.allclose(a.recording.y, c.recording.y)


def test_clean_recording_residual_is_the_noise(clean):
    r = clean.recording
    assert clean.effects == () and clean.sizes == {}
    assert (r.input_unit, r.output_unit) == ("V", "um")
    # The noise-free output is the plain base model's.
    path = jh.InputPath.from_samples(r.t, r.u)
    y_base = np.asarray(jh.simulate(clean.base, path, clean.solver))
    np.testing.assert_allclose(clean.noiseless, y_base, rtol=0, atol=1e-9)
    residual = r.y - y_base
    assert np.std(residual) == pytest.approx(clean.sigma, rel=0.1)
    assert abs(np.mean(residual)) < 5 * clean.sigma / np.sqrt(residual.size)
    assert 5e-4 <= clean.sigma / np.ptp(y_base) <= 2e-3


@pytest.mark.parametrize("effect", EFFECTS)
def test_effect_size_is_the_requested_number_of_sigmas(effect, clean):
    case = _case((effect,), seed=3, size_sigmas=5.0)
    assert case.effects == (effect,)
    assert case.sizes[effect] == pytest.approx(5.0, rel=0.1)
    # Independently: the same key gives the same input, base and noise, so the
    # difference to the clean record is the effect alone.
    np.testing.assert_array_equal(case.recording.u, clean.recording.u)
    assert clean.sigma == case.sigma
    change = case.noiseless - clean.noiseless
    assert _rms(change) / case.sigma == pytest.approx(5.0, rel=0.1)
    np.testing.assert_allclose(
        case.recording.y - case.noiseless, clean.recording.y - clean.noiseless
    )
    assert effect in case.truth_description


def test_default_sizes_are_drawn_between_3_and_10_sigmas():
    case = _case(("drift", "asymmetry"), seed=11)
    assert case.effects == ("asymmetry", "drift")  # catalogue order
    for effect in case.effects:
        assert 3.0 * 0.9 <= case.sizes[effect] <= 10.0 * 1.1


def test_a_pair_conceals_both_effects(clean):
    case = _case(("asymmetry", "input_bias"), seed=3, size_sigmas=6.0)
    assert set(case.sizes) == {"asymmetry", "input_bias"}
    for size in case.sizes.values():
        assert size == pytest.approx(6.0, rel=0.1)
    change = _rms(case.noiseless - clean.noiseless) / case.sigma
    assert 4.0 < change < 13.0  # the two add (not exactly: they interact)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_coloured_noise_is_strongly_correlated(seed):
    case = _case((), seed=seed, noise="coloured")
    e = case.recording.y - case.noiseless
    e = e - e.mean()
    lag1 = float(np.dot(e[1:], e[:-1]) / np.dot(e, e))
    assert lag1 > 0.8
    # Same marginal sigma (loosely: a strongly coloured series has few independent
    # samples).
    assert np.std(e) == pytest.approx(case.sigma, rel=0.35)


def test_white_noise_is_uncorrelated(clean):
    e = clean.recording.y - clean.noiseless
    e = e - e.mean()
    assert abs(float(np.dot(e[1:], e[:-1]) / np.dot(e, e))) < 0.1


def test_bad_arguments_are_rejected():
    key = jax.random.key(0)
    with pytest.raises(ValueError, match="valid names are asymmetry, input_bias"):
        jh.concealed_recording(("hysteresis",), key=key)
    with pytest.raises(TypeError, match="tuple of effect names"):
        jh.concealed_recording("creep", key=key)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="twice"):
        jh.concealed_recording(("creep", "creep"), key=key)
    with pytest.raises(ValueError, match="noise must be one of"):
        jh.concealed_recording((), key=key, noise="pink")
    with pytest.raises(TypeError, match="PRNG key"):
        jh.concealed_recording((), key=None)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="one size per effect"):
        jh.concealed_recording(("creep",), key=key, size_sigmas={"drift": 3.0})
    with pytest.raises(ValueError, match="positive"):
        jh.concealed_recording(("creep",), key=key, size_sigmas=-1.0)
    with pytest.raises(ValueError, match="duration"):
        jh.concealed_recording((), key=key, duration=0.0)


def test_truth_with_every_effect_off_is_the_base_model():
    model = jh.base_truth(jax.random.key(2))
    truth = jh.ConcealedTruth(model)
    path = jh.rich_excitation(jax.random.key(2), duration=4.0, rate=RATE)
    solver = jh.RK4(substeps=2)
    np.testing.assert_allclose(
        np.asarray(jh.simulate(truth, path, solver)),
        np.asarray(jh.simulate(model, path, solver)),
        rtol=0,
        atol=1e-12,
    )
    assert truth.parameters().keys() == model.parameters().keys()
    assert jh.bibo_stability(truth)


def test_demo_recording_is_fixed_by_default():
    demo = jh.demo_recording()
    assert demo.effects == ("asymmetry", "input_bias")
    r = demo.recording
    assert r.sample_rate == pytest.approx(1000.0)
    assert r.duration == pytest.approx(30.0)
    # u2 = 4 - 4 cos(0.2 pi t), scaled to 0..100 V.
    np.testing.assert_allclose(r.u, 50.0 * (1 - np.cos(0.2 * np.pi * r.t)), atol=1e-9)
    assert demo.sizes["asymmetry"] == pytest.approx(8.0, rel=0.1)
    assert demo.sizes["input_bias"] == pytest.approx(6.0, rel=0.1)
    again = jh.demo_recording(key=jax.random.key(2024))
    np.testing.assert_array_equal(r.y, again.recording.y)
