import importlib
from pathlib import Path

import jax
import numpy as np
import pytest

import jaxhyst as jh


DURATION, RATE = 8.0, 500.0


def _case(effects, seed=0, **kwargs):
    kwargs = {"duration": DURATION, "rate": RATE, **kwargs}
    return jh.synthetic.concealed_recording(effects, key=jax.random.key(seed), **kwargs)


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


@pytest.fixture(scope="module")
def clean():
    return _case((), seed=3)


def test_rich_excitation_is_a_piezo_drive():
    path = jh.synthetic.rich_excitation(jax.random.key(1), duration=DURATION, rate=RATE)
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
    a = jh.synthetic.rich_excitation(jax.random.key(4), duration=DURATION, rate=RATE)
    b = jh.synthetic.rich_excitation(jax.random.key(4), duration=DURATION, rate=RATE)
    c = jh.synthetic.rich_excitation(jax.random.key(5), duration=DURATION, rate=RATE)
    np.testing.assert_array_equal(a.values, b.values)
    assert not np.allclose(a.values, c.values)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_base_truth_is_a_stable_paper_like_model(seed):
    model = jh.synthetic.base_truth(jax.random.key(seed))
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


@pytest.mark.parametrize("effect", jh.families.EFFECT_NAMES)
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
        jh.synthetic.concealed_recording(("hysteresis",), key=key)
    with pytest.raises(TypeError, match="tuple of effect names"):
        jh.synthetic.concealed_recording("creep", key=key)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="twice"):
        jh.synthetic.concealed_recording(("creep", "creep"), key=key)
    with pytest.raises(ValueError, match="noise must be one of"):
        jh.synthetic.concealed_recording((), key=key, noise="pink")
    with pytest.raises(TypeError, match="PRNG key"):
        jh.synthetic.concealed_recording((), key=None)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="one size per effect"):
        jh.synthetic.concealed_recording(
            ("creep",), key=key, size_sigmas={"drift": 3.0}
        )
    with pytest.raises(ValueError, match="positive"):
        jh.synthetic.concealed_recording(("creep",), key=key, size_sigmas=-1.0)
    with pytest.raises(ValueError, match="duration"):
        jh.synthetic.concealed_recording((), key=key, duration=0.0)


def test_effect_names_are_the_catalogues():
    from jaxhyst.synthetic._sizing import _SIZERS

    # One truth form per catalogue effect, in the catalogue's order (the order sets
    # each effect's key, so it is part of what a seed means).
    assert tuple(_SIZERS) == jh.families.EFFECT_NAMES


def test_truth_with_every_effect_off_is_the_base_model():
    model = jh.synthetic.base_truth(jax.random.key(2))
    truth = jh.synthetic.ConcealedTruth(model)
    path = jh.synthetic.rich_excitation(jax.random.key(2), duration=4.0, rate=RATE)
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
    demo = jh.synthetic.demo_recording()
    assert demo.effects == ("asymmetry", "input_bias")
    r = demo.recording
    assert r.sample_rate == pytest.approx(1000.0)
    assert r.duration == pytest.approx(30.0)
    # u2 = 4 - 4 cos(0.2 pi t), scaled to 0..100 V.
    np.testing.assert_allclose(r.u, 50.0 * (1 - np.cos(0.2 * np.pi * r.t)), atol=1e-9)
    assert demo.sizes["asymmetry"] == pytest.approx(8.0, rel=0.1)
    assert demo.sizes["input_bias"] == pytest.approx(6.0, rel=0.1)
    again = jh.synthetic.demo_recording(key=jax.random.key(2024))
    np.testing.assert_array_equal(r.y, again.recording.y)


# ------------------------------------------------------------ practical records

SHORT, SLOW_RATE = 5.0, 200.0


def _spectrum_peaks(u, rate, count):
    """The `count` strongest frequencies (Hz) of u minus its mean, strongest first."""
    u = np.asarray(u)[:-1]  # whole periods: drop the closing sample
    magnitude = np.abs(np.fft.rfft(u - u.mean()))
    freqs = np.fft.rfftfreq(u.size, 1 / rate)
    return [float(freqs[i]) for i in np.argsort(magnitude)[::-1][:count]], magnitude


def test_sine_excitation_is_one_sine_from_rest():
    path = jh.synthetic.SineExcitation((1.0,)).path(SHORT, SLOW_RATE)
    u = np.asarray(path.values)
    assert path.num_samples == round(SHORT * SLOW_RATE) + 1
    assert float(path.t1 - path.t0) == pytest.approx(SHORT)
    assert u[0] == pytest.approx(0.0, abs=1e-12)  # at rest at the trough
    assert u.min() >= -1e-9 and u.max() == pytest.approx(100.0)
    peaks, _ = _spectrum_peaks(u, SLOW_RATE, 1)
    assert peaks == [pytest.approx(1.0)]


def test_two_sines_summed_share_the_amplitude():
    path = jh.synthetic.SineExcitation((1.0, 5.0), amplitude=40.0, offset=50.0).path(
        SHORT, SLOW_RATE
    )
    u = np.asarray(path.values)
    assert u.min() >= 10.0 - 1e-9 and u.max() <= 90.0 + 1e-9
    peaks, magnitude = _spectrum_peaks(u, SLOW_RATE, 2)
    assert sorted(peaks) == [pytest.approx(1.0), pytest.approx(5.0)]
    at = lambda f: magnitude[round(f * SHORT)]
    assert at(1.0) == pytest.approx(at(5.0), rel=1e-6)  # one amplitude


def test_sines_in_sequence_play_one_after_the_other():
    duration = 8.0
    u = np.asarray(
        jh.synthetic.SineExcitation((0.5, 2.0), in_sequence=True)
        .path(duration, SLOW_RATE)
        .values
    )
    half = round(duration / 2 * SLOW_RATE)
    first, _ = _spectrum_peaks(u[: half + 1], SLOW_RATE, 1)
    second, _ = _spectrum_peaks(u[half:], SLOW_RATE, 1)
    assert first == [pytest.approx(0.5)] and second == [pytest.approx(2.0)]
    assert u[half] == pytest.approx(0.0, abs=1e-9)  # each part ends at rest


def test_switch_on_sine_holds_then_steps_into_the_sine():
    drive = jh.synthetic.SwitchOnSine(
        1.0, hold=1.5, rest=0.0, offset=50.0, amplitude=40.0
    )
    path = drive.path(SHORT + 1.5, SLOW_RATE)
    t, u = np.asarray(path.times), np.asarray(path.values)
    assert float(path.t1) == pytest.approx(SHORT + 1.5)
    held = t <= 1.5
    assert np.all(u[held] == 0.0)  # flat at rest before the switch-on
    running = t >= 1.5 + drive.rise
    np.testing.assert_allclose(
        u[running],
        50.0 + 40.0 * np.sin(2 * np.pi * (t[running] - 1.5 - drive.rise)),
        atol=1e-9,
    )
    assert u.max() <= 90.0 + 1e-9


def test_practical_recording_shares_input_base_and_noise():
    drive = jh.synthetic.SineExcitation((1.0,))
    make = lambda effects: jh.synthetic.practical_recording(
        effects,
        key=jax.random.key(4),
        excitation=drive,
        duration=SHORT,
        rate=SLOW_RATE,
        size_sigmas=5.0,
    )
    clean, creep = make(()), make(("creep",))
    assert creep.effects == ("creep",)
    np.testing.assert_array_equal(creep.recording.u, clean.recording.u)
    np.testing.assert_array_equal(
        creep.recording.u, drive.path(SHORT, SLOW_RATE).values
    )
    assert creep.base == clean.base and creep.sigma == clean.sigma
    np.testing.assert_allclose(
        creep.recording.y - creep.noiseless, clean.recording.y - clean.noiseless
    )
    change = _rms(creep.noiseless - clean.noiseless) / creep.sigma
    assert change == pytest.approx(5.0, rel=0.1)
    assert creep.sizes["creep"] == pytest.approx(5.0, rel=0.1)
    assert creep.truth_description.startswith("input: sine 1 Hz")


def test_practical_recording_reports_a_size_the_input_cannot_show():
    # A stage mode is never shown with a participation above 1: on a slow sine it
    # cannot reach 1000 sigma, and the description says so.
    case = jh.synthetic.practical_recording(
        ("dynamics",),
        key=jax.random.key(0),
        excitation=jh.synthetic.SineExcitation((0.5,)),
        duration=4.0,
        rate=SLOW_RATE,
        size_sigmas=1000.0,
    )
    assert case.sizes["dynamics"] < 500.0
    assert "requested 1e+03 sigma: this input does not show more" in (
        case.truth_description
    )


def test_practical_arguments_are_rejected_clearly():
    key = jax.random.key(0)
    drive = jh.synthetic.SineExcitation((1.0,))
    with pytest.raises(TypeError, match="excitation must be an excitation object"):
        jh.synthetic.practical_recording((), key=key, excitation="sine")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="valid names are"):
        jh.synthetic.practical_recording(("hum",), key=key, excitation=drive)
    with pytest.raises(ValueError, match="duration"):
        jh.synthetic.practical_recording((), key=key, excitation=drive, duration=-1.0)
    with pytest.raises(ValueError, match="noise must be one of"):
        jh.synthetic.practical_recording((), key=key, excitation=drive, noise="pink")
    with pytest.raises(ValueError, match="pass duration >= 2"):
        jh.synthetic.SineExcitation((0.5,)).path(1.0, SLOW_RATE)
    with pytest.raises(ValueError, match="pass duration >= 4"):
        jh.synthetic.SineExcitation((0.5, 2.0), in_sequence=True).path(3.0, SLOW_RATE)
    with pytest.raises(ValueError, match="pass duration >= 3"):
        jh.synthetic.SwitchOnSine(1.0, hold=2.0, rise=0.5).path(3.0, SLOW_RATE)
    with pytest.raises(ValueError, match="pass rate >= 100"):
        jh.synthetic.SineExcitation((1.0, 5.0)).path(SHORT, 50.0)
    with pytest.raises(TypeError, match="tuple of frequencies"):
        jh.synthetic.SineExcitation("1 Hz")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="at least one frequency"):
        jh.synthetic.SineExcitation(())
    with pytest.raises(ValueError, match="repeated"):
        jh.synthetic.SineExcitation((1.0, 1.0))
    with pytest.raises(ValueError, match="frequencies must be positive"):
        jh.synthetic.SineExcitation((-1.0,))
    with pytest.raises(ValueError, match="unipolar 0..100 V"):
        jh.synthetic.SineExcitation((1.0,), amplitude=50.0, offset=40.0)
    with pytest.raises(ValueError, match="rest level"):
        jh.synthetic.SwitchOnSine(1.0, rest=-5.0)
    with pytest.raises(ValueError, match="hold must be positive"):
        jh.synthetic.SwitchOnSine(1.0, hold=0.0)


def _benchmark_module(monkeypatch, name):
    benchmarks = Path(__file__).resolve().parent.parent / "benchmarks"
    monkeypatch.syspath_prepend(str(benchmarks))
    return importlib.import_module(name)


def test_benchmark_classify_covers_every_outcome(monkeypatch):
    classify = _benchmark_module(monkeypatch, "practical_records").classify
    s = lambda *names: frozenset(names)
    assert classify(s("creep"), s("creep"), s()) == "exact"
    assert classify(s(), s(), s("creep", "drift")) == "exact"
    # Named a rival it cannot tell from the truth, and said so.
    assert (
        classify(s("creep"), s("rate_dependence"), s("creep", "rate_dependence"))
        == "cannot tell"
    )
    assert classify(s("input_bias"), s(), s("input_bias")) == "cannot tell"
    # An unflagged extra is a false claim, even when the truth was also named.
    assert classify(s(), s("drift"), s()) == "false claim"
    assert classify(s("creep"), s("creep", "drift"), s("creep")) == "false claim"
    assert classify(s("creep"), s("rate_dependence"), s("creep")) == "false claim"
    assert classify(s("creep"), s(), s()) == "missed"
    assert classify(s("creep"), s("rate_dependence"), s("rate_dependence")) == (
        "missed"
    )


def test_benchmark_suite_summary_splits_the_median_seconds(monkeypatch):
    common = _benchmark_module(monkeypatch, "_common")

    def case(effects, named, seconds):
        return {
            "effects": effects,
            "named": named,
            "exact": set(effects) == set(named),
            "final_over_sigma": 1.0,
            "seconds": seconds,
            "noise": "white",
        }

    report = {
        "cases": [
            case(["offset"], ["offset"], 10.0),
            case(["offset", "asymmetry"], ["offset"], 30.0),
            case([], [], 5.0),
        ]
    }
    summary = common.score_suite(
        report, ("offset", "asymmetry"), 1.3, effect_cases_only=True
    )
    assert summary["median_seconds"] == 10.0
    assert summary["median_seconds_effect_cases"] == 20.0
    assert summary["median_seconds_clean_cases"] == 5.0
    assert summary["exact_set_accuracy"] == 0.5
