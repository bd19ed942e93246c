import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxhyst as jh


@eqx.filter_jit
def _call(signal, t):
    return signal(t)


@eqx.filter_jit
def _grad_t(signal, t):
    return jax.vmap(jax.grad(lambda s: signal(s)))(jnp.asarray(t, float))


def _central_difference(signal, t, h=1e-6):
    t = np.asarray(t)
    return (np.asarray(_call(signal, t + h)) - np.asarray(_call(signal, t - h))) / (
        2 * h
    )


def _upward_crossings(values, level):
    values = np.asarray(values) - level
    return int(np.sum((values[:-1] < 0) & (values[1:] >= 0)))


def test_paper_inputs_at_known_points():
    u1, u2 = jh.paper_u1(), jh.paper_u2(periods=3)
    assert u1.duration == 10.0 and u2.duration == 30.0
    t = jnp.array([0.0, 2.5, 5.0, 7.5, 10.0])
    np.testing.assert_allclose(u1(t), [0, 2, 4, 2, 0], atol=1e-12)
    np.testing.assert_allclose(u2(t), [0, 4, 8, 4, 0], atol=1e-12)
    np.testing.assert_allclose(u1(5.0), 4.0)
    np.testing.assert_allclose(u1(0), 0.0)  # integer time is accepted
    t = np.linspace(0, 10, 37)
    np.testing.assert_allclose(u1(t), 2 - 2 * np.cos(0.2 * np.pi * t), atol=1e-12)


@pytest.mark.parametrize(
    "signal",
    [
        jh.paper_u1(),
        jh.DecayingCosine(1.5, 0.5, 3.0, duration=6.0, offset=0.5),
        jh.Triangle(1.0, 0.3, duration=5.0),
        jh.Chirp(0.1, 2.0, 1.0, duration=4.0),
        jh.Chirp(0.1, 2.0, 1.0, duration=4.0, logarithmic=True),
        jh.Multisine([0.5, 1.0], [1.0, 0.5], [0.1, 0.2], duration=2.0),
        jh.StepHold([0.0, 2.0, -1.0], hold_time=1.0, ramp_time=0.5),
        jh.Concatenate([jh.paper_u1(), jh.Constant(0.0, duration=2.0), jh.paper_u2()]),
        jh.Constant(3.0, duration=1.0),
    ],
)
def test_shape_jit_and_grad(signal):
    t = jnp.linspace(0.01, signal.duration - 0.01, 12).reshape(3, 4)
    u = _call(signal, t)
    assert u.shape == (3, 4)
    np.testing.assert_allclose(jax.vmap(signal)(t.ravel()), u.ravel(), rtol=1e-12)
    assert signal(1.0).shape == ()  # eager
    # Avoid kinks (triangle corners, step-hold corners) for the finite difference.
    flat = np.linspace(0.013, signal.duration - 0.017, 9)
    grad = _grad_t(signal, flat)
    assert np.all(np.isfinite(grad))
    np.testing.assert_allclose(
        grad, _central_difference(signal, flat), rtol=1e-5, atol=1e-6
    )


def test_grad_with_respect_to_coefficients():
    def peak(amplitude):
        return jh.RaisedCosine(amplitude, 0.1, duration=10.0)(5.0)

    np.testing.assert_allclose(jax.grad(peak)(jnp.array(2.0)), 2.0)


def test_decaying_cosine_shrinks_toward_offset():
    signal = jh.DecayingCosine(2.0, 0.1, 20.0, duration=40.0, offset=1.0)
    np.testing.assert_allclose(
        _call(signal, jnp.array([0.0, 10.0, 20.0])), 1.0, atol=1e-12
    )
    peaks = _call(signal, jnp.array([5.0, 15.0, 25.0]))
    assert np.all(np.diff(peaks) < 0) and np.all(peaks > 1.0)
    np.testing.assert_allclose(peaks[0], 1.0 + 4.0 * math.exp(-5.0 / 20.0))


def test_multisine_rms_and_determinism():
    duration = 10.0
    frequencies = jnp.arange(1, 21) / duration
    key = jax.random.key(0)
    signal = jh.Multisine.random_phase(
        key, frequencies, rms=0.7, duration=duration, offset=2.0
    )
    t = jh.sample_times(signal, 200.0)[:-1]  # one full period
    u = np.asarray(_call(signal, t))
    np.testing.assert_allclose(np.mean(u), 2.0, atol=1e-10)
    np.testing.assert_allclose(np.sqrt(np.mean((u - 2.0) ** 2)), 0.7, rtol=1e-6)
    again = jh.Multisine.random_phase(key, frequencies, rms=0.7, duration=duration)
    np.testing.assert_array_equal(signal.phases, again.phases)
    other = jh.Multisine.random_phase(
        jax.random.key(1), frequencies, rms=0.7, duration=duration
    )
    assert not np.allclose(signal.phases, other.phases)
    assert np.all((signal.phases >= 0) & (signal.phases < 2 * np.pi))


@pytest.mark.parametrize("logarithmic", [False, True])
def test_chirp_instantaneous_frequency(logarithmic):
    f0, f1, duration = 1.0, 8.0, 10.0
    signal = jh.Chirp(
        f0, f1, 1.5, duration=duration, offset=-1.0, logarithmic=logarithmic
    )
    np.testing.assert_allclose(signal(0.0), -1.0)
    t = jh.sample_times(signal, 2000.0)
    u = _call(signal, t)
    # Cycles counted from crossings of the mean level agree with the phase integral.
    if logarithmic:
        cycles = (f1 - f0) * duration / math.log(f1 / f0)
    else:
        cycles = 0.5 * (f0 + f1) * duration
    assert abs(_upward_crossings(u, 0.5) - cycles) <= 1
    np.testing.assert_allclose(signal.phase(duration), 2 * np.pi * cycles, rtol=1e-9)
    # Local cycle count over a short window matches the instantaneous frequency.
    for start in (1.0, 5.0, 8.0):
        window = (t >= start) & (t < start + 1.0)
        expected = signal.instantaneous_frequency(start + 0.5)
        assert abs(_upward_crossings(u[window], 0.5) - expected) <= 1
    np.testing.assert_allclose(signal.instantaneous_frequency(0.0), f0)
    np.testing.assert_allclose(signal.instantaneous_frequency(duration), f1)
    # Phase derivative equals 2 pi times the instantaneous frequency.
    times = jnp.array([0.0, 0.3, 4.0, 9.9])
    np.testing.assert_allclose(
        jax.vmap(jax.grad(signal.phase))(times),
        2 * np.pi * signal.instantaneous_frequency(times),
        rtol=1e-9,
    )


def test_log_chirp_with_equal_frequencies_is_a_raised_cosine():
    chirp = jh.Chirp(0.5, 0.5, 1.0, duration=4.0, logarithmic=True)
    cosine = jh.RaisedCosine(1.0, 0.5, duration=4.0)
    t = jnp.linspace(0, 4, 17)
    np.testing.assert_allclose(_call(chirp, t), _call(cosine, t), atol=1e-12)


def test_triangle_peak_and_slope():
    amplitude, frequency, offset = 1.5, 0.25, 0.5
    signal = jh.Triangle(amplitude, frequency, duration=8.0, offset=offset)
    np.testing.assert_allclose(signal(0.0), offset)
    np.testing.assert_allclose(signal(2.0), offset + 2 * amplitude)  # half period
    np.testing.assert_allclose(signal(4.0), offset, atol=1e-12)
    np.testing.assert_allclose(signal(1.0), offset + amplitude)
    slope = 4 * amplitude * frequency
    np.testing.assert_allclose(_grad_t(signal, [0.5, 1.7, 4.2]), slope)
    np.testing.assert_allclose(_grad_t(signal, [2.5, 3.9, 6.1]), -slope)
    t = jh.sample_times(signal, 100.0)
    assert np.max(_call(signal, t)) <= offset + 2 * amplitude + 1e-12
    assert np.min(_call(signal, t)) >= offset - 1e-12


def test_step_hold_levels_and_ramps():
    levels = [0.0, 50.0, 100.0, 20.0]
    signal = jh.StepHold(levels, hold_time=2.0, ramp_time=0.5)
    assert signal.duration == 4 * 2.0 + 3 * 0.5
    for i, level in enumerate(levels):
        start = i * 2.5
        np.testing.assert_allclose(
            _call(signal, jnp.linspace(start, start + 2.0, 9)), level, atol=1e-12
        )
    # Ramps are linear between holds.
    np.testing.assert_allclose(signal(2.25), 25.0)
    np.testing.assert_allclose(_grad_t(signal, [2.1, 7.2]), [100.0, -160.0])
    # Outside [0, duration] the end levels hold.
    np.testing.assert_allclose(_call(signal, jnp.array([-1.0, 20.0])), [0.0, 20.0])


def test_concatenate_continuity():
    u1 = jh.paper_u1()
    hold = jh.Constant(0.0, duration=3.0)
    signal = jh.Concatenate([u1, hold, jh.Triangle(2.0, 0.1, duration=10.0)])
    assert signal.duration == 23.0
    np.testing.assert_allclose(
        _call(signal, jnp.array([5.0, 11.0, 13.0, 18.0])), [4, 0, 0, 4]
    )
    t = jh.sample_times(signal, 100.0)
    u = np.asarray(_call(signal, t))
    assert np.max(np.abs(np.diff(u))) < 0.2  # no jumps at the junctions
    assert np.all(np.isfinite(_grad_t(signal, [0.0, 10.0, 13.0, 23.0])))


def test_concatenate_rejects_jumps():
    with pytest.raises(ValueError, match=r"junction 0 \(t=10\).*allow_jumps=True"):
        jh.Concatenate([jh.paper_u1(), jh.Constant(1.0, duration=2.0)])
    with pytest.raises(ValueError, match="jump of 0.5"):
        jh.Concatenate(
            [
                jh.paper_u1(),
                jh.Constant(0.0, duration=1.0),
                jh.Constant(0.5, duration=1.0),
            ]
        )
    signal = jh.Concatenate(
        [jh.paper_u1(), jh.Constant(1.0, duration=2.0)], allow_jumps=True
    )
    np.testing.assert_allclose(
        _call(signal, jnp.array([9.999999, 10.0, 11.0])), [0, 1, 1], atol=1e-9
    )
    jh.Concatenate([jh.paper_u1(), jh.Constant(1e-3, duration=1.0)], atol=1e-2)


def test_concatenate_overflow_in_unselected_part_does_not_poison_gradient():
    decay = jh.DecayingCosine(1.0, 1.0, 0.01, duration=1.0)
    signal = jh.Concatenate([jh.Constant(0.0, duration=100.0), decay])
    assert np.all(np.isfinite(_grad_t(signal, [0.0, 50.0, 100.5])))


def test_sample_length_and_end_time():
    signal = jh.paper_u1()
    path = jh.sample(signal, 1000.0)
    assert isinstance(path, jh.InputPath)
    assert path.num_samples == 10001
    np.testing.assert_allclose(path.t1, 10.0)
    np.testing.assert_allclose(path.dt, 1e-3)
    np.testing.assert_allclose(path.values, _call(signal, path.times), atol=1e-12)
    times = jh.sample_times(signal, 1000.0)
    assert isinstance(times, np.ndarray) and times.shape == (10001,)
    assert times[0] == 0.0 and times[-1] == 10.0
    cubic = jh.sample(signal, 10.0, interpolation=jh.CubicInterpolation())
    assert isinstance(cubic.interpolation, jh.CubicInterpolation)
    assert jh.sample(jh.Constant(1.0, duration=0.5), 2).num_samples == 2


def test_sample_under_jit_with_traced_coefficients():
    @jax.jit
    def values(amplitude):
        return jh.sample(jh.RaisedCosine(amplitude, 0.1, duration=10.0), 10.0).values

    np.testing.assert_allclose(
        values(jnp.array(2.0)), jh.sample(jh.paper_u1(), 10.0).values
    )


def test_module_is_a_pytree():
    signal = jh.Multisine([1.0, 2.0], [1.0, 1.0], [0.0, 0.0], duration=1.0)
    leaves = jax.tree_util.tree_leaves(eqx.filter(signal, eqx.is_array))
    assert len(leaves) == 3
    batched = jax.vmap(lambda a: jh.RaisedCosine(a, 0.1, duration=10.0)(5.0))(
        jnp.array([1.0, 2.0])
    )
    np.testing.assert_allclose(batched, [2.0, 4.0])


@pytest.mark.parametrize(
    "build, match",
    [
        (lambda: jh.RaisedCosine(1.0, 0.0, duration=1.0), r"frequency=0.0\).*positive"),
        (lambda: jh.RaisedCosine(1.0, 0.1, duration=0.0), "duration must be positive"),
        (
            lambda: jh.RaisedCosine(np.nan, 0.1, duration=1.0),
            "amplitude must be finite",
        ),
        (lambda: jh.DecayingCosine(1.0, 0.1, -1.0, duration=1.0), "decay_time"),
        (lambda: jh.Triangle(1.0, -0.1, duration=1.0), "frequency"),
        (lambda: jh.Chirp(0.0, 1.0, 1.0, duration=1.0, logarithmic=True), "f0"),
        (lambda: jh.Chirp(0.0, 0.0, 1.0, duration=1.0), "Constant"),
        (lambda: jh.Chirp(1.0, -1.0, 1.0, duration=1.0), "f1"),
        (
            lambda: jh.Multisine([1.0, 2.0], [1.0], [0.0, 0.0], duration=1.0),
            "amplitudes",
        ),
        (lambda: jh.Multisine([[1.0]], [[1.0]], [[0.0]], duration=1.0), "1-D"),
        (lambda: jh.Multisine([0.0], [1.0], [0.0], duration=1.0), "frequencies"),
        (
            lambda: jh.Multisine.random_phase(
                jax.random.key(0), [1.0, 1.0], rms=1.0, duration=1.0
            ),
            "distinct",
        ),
        (
            lambda: jh.Multisine.random_phase(
                jax.random.key(0), [1.0], rms=0.0, duration=1.0
            ),
            "rms",
        ),
        (lambda: jh.StepHold([1.0], hold_time=1.0, ramp_time=1.0), "Constant"),
        (lambda: jh.StepHold([0.0, 1.0], hold_time=-1.0, ramp_time=1.0), "hold_time"),
        (lambda: jh.StepHold([0.0, 1.0], hold_time=1.0, ramp_time=0.0), "short ramp"),
        (lambda: jh.Concatenate([]), "empty"),
        (lambda: jh.Concatenate([jnp.zeros(3)]), r"signals\[0\]"),
        (lambda: jh.Constant(1.0, duration=-2.0), "duration"),
        (lambda: jh.paper_u1(periods=0), "periods"),
        (lambda: jh.paper_u2(periods=-1), "periods"),
        (lambda: jh.sample(jh.paper_u1(), 0.0), "rate must be positive"),
        (lambda: jh.sample(jh.paper_u1(), -5.0), "rate"),
        (lambda: jh.sample(jh.paper_u1(), 0.01), "only 1 sample"),
        (lambda: jh.sample(jh.paper_u1(), jnp.array(10.0)), "Python number"),
        (lambda: jh.sample_times(jh.paper_u1(), math.inf), "finite"),
    ],
)
def test_validation_errors(build, match):
    with pytest.raises(ValueError, match=match):
        build()


def test_concatenate_checks_concrete_parts_under_jit():
    @jax.jit
    def build(t):
        return jh.Concatenate([jh.paper_u1(), jh.Constant(1.0, duration=2.0)])(t)

    with pytest.raises(ValueError, match="allow_jumps"):
        build(1.0)

    @jax.jit
    def traced(level, t):
        parts = [jh.paper_u1(), jh.Constant(level, duration=2.0)]
        return jh.Concatenate(parts)(t)

    np.testing.assert_allclose(traced(0.0, 11.0), 0.0)
