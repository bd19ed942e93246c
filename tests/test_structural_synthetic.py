import equinox as eqx
import jax
import numpy as np
import pytest

import jaxhyst as jh
from jaxhyst.synthetic import (
    STRUCTURAL_FORMS,
    StructuralTruth,
    loading_protocol,
    structural_base_truth,
    structural_recording,
)


POINTS = 1000


def _case(effects, seed=0, **kwargs):
    kwargs = {"points": POINTS, **kwargs}
    return structural_recording(effects, key=jax.random.key(seed), **kwargs)


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


_simulate_jit = eqx.filter_jit(jh.simulate)


def _simulate(model, case):
    path = jh.InputPath(0.0, 1.0, case.recording.u)
    return np.asarray(_simulate_jit(model, path, case.solver))


def _turning_points(x):
    slope = np.diff(x)
    return np.flatnonzero(np.sign(slope[1:]) != np.sign(slope[:-1])) + 1


@pytest.fixture(scope="module")
def clean():
    return _case((), seed=3)


def test_determinism_per_key():
    a = _case(("pinching",), seed=7, noise="coloured", protocol="earthquake")
    b = _case(("pinching",), seed=7, noise="coloured", protocol="earthquake")
    c = _case(("pinching",), seed=8, noise="coloured", protocol="earthquake")
    np.testing.assert_array_equal(a.recording.y, b.recording.y)
    np.testing.assert_array_equal(a.recording.u, b.recording.u)
    assert a.sizes == b.sizes and a.forms == b.forms
    assert a.truth_description == b.truth_description
    assert not np.allclose(a.recording.u, c.recording.u)
    assert not np.allclose(a.recording.y, c.recording.y)


def test_clean_record_is_the_base_plus_noise(clean):
    r = clean.recording
    assert clean.effects == () and clean.sizes == {} and clean.forms == {}
    assert (r.input_unit, r.output_unit, r.time_unit) == ("mm", "kN", "sample")
    np.testing.assert_array_equal(r.t, np.arange(POINTS))  # the pseudo time
    y_base = _simulate(clean.base, clean)
    np.testing.assert_allclose(clean.noiseless, y_base, rtol=0, atol=1e-9)
    residual = r.y - y_base
    assert np.std(residual) == pytest.approx(clean.sigma, rel=0.1)
    assert abs(np.corrcoef(residual[1:], residual[:-1])[0, 1]) < 0.15  # white
    # The noise is about 1 % of the peak force.
    assert 0.005 < clean.sigma / np.max(np.abs(y_base)) < 0.02


def test_truth_with_every_effect_off_is_the_base(clean):
    off = StructuralTruth(clean.base)
    np.testing.assert_allclose(
        _simulate(off, clean), _simulate(clean.base, clean), rtol=0, atol=1e-9
    )


def test_coloured_noise_is_correlated_with_the_same_sigma():
    case = _case((), seed=4, noise="coloured")
    residual = case.recording.y - case.noiseless
    lag1 = np.corrcoef(residual[1:], residual[:-1])[0, 1]
    assert 0.45 < lag1 < 0.95
    assert np.std(residual) == pytest.approx(case.sigma, rel=0.35)


def test_effects_change_only_the_effects():
    """The same key with other effects: the same base, displacement and noise."""
    clean = _case((), seed=5)
    drift = _case(("drift",), seed=5)
    np.testing.assert_array_equal(clean.recording.u, drift.recording.u)
    np.testing.assert_allclose(
        clean.recording.y - clean.noiseless,
        drift.recording.y - drift.noiseless,
        atol=1e-9,
    )


@pytest.mark.parametrize("effect", jh.families.STRUCTURAL_EFFECT_NAMES)
@pytest.mark.parametrize("protocol", ["cyclic", "earthquake"])
def test_requested_size_is_met(effect, protocol):
    case = _case((effect,), seed=11, protocol=protocol, size_sigmas=6.0)
    y_base = _simulate(case.base, case)
    change = _simulate(case.truth, case) - y_base
    np.testing.assert_allclose(case.noiseless - y_base, change, atol=1e-9)
    assert _rms(change) / case.sigma == pytest.approx(6.0, rel=0.1)
    assert case.sizes[effect] == pytest.approx(6.0, rel=0.01)
    assert case.forms[effect] in STRUCTURAL_FORMS[effect]
    assert case.effects == (effect,)


def test_pair_sizes_and_default_sizes():
    case = _case(("pinching", "degradation"), seed=2)
    assert case.effects == ("degradation", "pinching")  # catalogue order
    for effect in case.effects:
        assert 4.0 * 0.98 <= case.sizes[effect] <= 12.0 * 1.01
    sized = _case(
        ("degradation", "pinching"),
        seed=2,
        size_sigmas={"degradation": 5.0, "pinching": 9.0},
    )
    assert sized.sizes["degradation"] == pytest.approx(5.0, rel=0.01)
    assert sized.sizes["pinching"] == pytest.approx(9.0, rel=0.01)


@pytest.mark.parametrize("effect", ["degradation", "pinching", "asymmetry"])
def test_both_forms_are_reachable(effect):
    seen = set()
    for seed in range(12):
        seen.add(_case((effect,), seed=seed, size_sigmas=5.0).forms[effect])
        if seen == set(STRUCTURAL_FORMS[effect]):
            break
    assert seen == set(STRUCTURAL_FORMS[effect])


def test_pinching_forms_pinch_the_loop():
    """Near zero force the pinched record is softer: with nearly uniform
    displacement steps, more samples lie in a band around zero force."""
    forms = set()
    for seed in (0, 2):  # a slip gap, a Baber-Noori slip-lock
        case = _case(("pinching",), seed=seed, size_sigmas=12.0)
        forms.add(case.forms["pinching"])
        x = case.recording.u
        pinched, base = case.noiseless, _simulate(case.base, case)
        late = np.arange(x.size) > x.size // 2
        band = 0.1 * np.max(np.abs(base))
        inside = [np.sum(late & (np.abs(f) < band)) for f in (pinched, base)]
        assert inside[0] > 1.3 * inside[1]
    assert forms == set(STRUCTURAL_FORMS["pinching"])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_cyclic_protocol_grows_in_levels_of_two_or_three_cycles(seed):
    x_y = 6.0
    path, what = loading_protocol(
        jax.random.key(seed), yield_displacement=x_y, protocol="cyclic", points=1500
    )
    x = np.asarray(path.values)
    assert x.shape == (1500,) and float(path.dt) == 1.0 and float(path.t0) == 0.0
    assert x[0] == 0.0 and x[-1] == 0.0
    peaks = x[_turning_points(x)]
    top = np.abs(peaks[peaks * peaks[0] > 0])  # the first direction's peaks
    levels, counts = np.unique(np.round(top, 9), return_counts=True)
    assert 6 <= levels.size <= 10
    assert set(counts) <= {2, 3} and len(set(counts)) == 1
    # Stepwise growth: each level's cycles together, levels in increasing order.
    assert np.all(np.diff(top) >= -1e-9)
    assert np.all(np.diff(levels) > 0)
    assert 0.2 * x_y <= levels[0] <= 0.5 * x_y and 4 * x_y <= levels[-1] <= 8 * x_y
    # As a controller samples: nearly uniform displacement increments.
    dx = np.abs(np.diff(x))
    assert np.max(dx) <= 2.0 * np.mean(dx)
    assert f"x {counts[0]} cycles" in what


@pytest.mark.parametrize("seed", [0, 1])
def test_earthquake_protocol_is_an_enveloped_random_history(seed):
    x_y = 8.0
    path, _ = loading_protocol(
        jax.random.key(seed), yield_displacement=x_y, protocol="earthquake", points=2000
    )
    x = np.asarray(path.values)
    assert x.shape == (2000,)
    assert x[0] == 0.0 and x[-1] == 0.0
    assert 3 * x_y <= np.max(np.abs(x)) <= 6 * x_y + 1e-9
    peaks = np.abs(x[_turning_points(x)])
    assert peaks.size >= 20
    assert np.unique(np.round(peaks, 6)).size > 0.8 * peaks.size  # not repeated
    # Enveloped: quiet at the start, strong in the middle.
    assert _rms(x[:50]) < 0.5 * _rms(x[500:1000])
    dx = np.abs(np.diff(x))
    assert np.max(dx) <= 2.0 * np.mean(dx)


def test_base_truth_is_a_test_like_bouc_wen():
    for seed in range(4):
        base = structural_base_truth(jax.random.key(seed))
        p = {k: float(v) for k, v in base.parameters().items()}
        assert p["D"] == 1.0 and p["A"] == 1.0
        assert 0.02 <= p["alpha"] <= 0.12 and 1.0 <= p["n"] <= 3.0
        assert p["beta"] >= abs(p["gamma"])
        x_y = float(StructuralTruth(base).yield_displacement)
        assert 4.0 <= x_y <= 15.0
        assert 80.0 <= float(StructuralTruth(base).yield_force) <= 800.0


@pytest.mark.parametrize(
    "kwargs, error, words",
    [
        ({"effects": "pinching"}, TypeError, "tuple of effect names"),
        ({"effects": ("slip",)}, ValueError, "degradation, pinching, asymmetry"),
        ({"effects": ("drift", "drift")}, ValueError, "twice"),
        ({"noise": "pink"}, ValueError, "white, coloured"),
        ({"protocol": "monotonic"}, ValueError, "cyclic, earthquake"),
        ({"points": 100}, ValueError, "points must be between"),
        ({"points": 2000.0}, TypeError, "points must be an integer"),
        ({"size_sigmas": -1.0}, ValueError, "positive"),
        ({"size_sigmas": {"pinching": 5.0}}, ValueError, "one size per effect"),
        ({"key": None}, TypeError, "jax.random.key(0)"),
        ({"key": 3}, TypeError, "PRNG key"),
    ],
)
def test_bad_arguments_raise_clear_errors(kwargs, error, words):
    arguments = {"effects": ("drift",), "key": jax.random.key(0), **kwargs}
    effects = arguments.pop("effects")
    with pytest.raises(error) as info:
        structural_recording(effects, **arguments)
    assert words in str(info.value)
    assert "structural_recording" in str(info.value)


def test_effect_names_are_the_catalogues():
    from jaxhyst.synthetic._structural_sizing import _SIZERS

    assert tuple(_SIZERS) == jh.families.STRUCTURAL_EFFECT_NAMES
    assert tuple(STRUCTURAL_FORMS) == jh.families.STRUCTURAL_EFFECT_NAMES


def test_bad_protocol_arguments():
    with pytest.raises(ValueError, match="yield_displacement"):
        loading_protocol(jax.random.key(0), yield_displacement=-1.0)
    with pytest.raises(ValueError, match="protocol must be one of"):
        loading_protocol(jax.random.key(0), yield_displacement=5.0, protocol="ramp")
