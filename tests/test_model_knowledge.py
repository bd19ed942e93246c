"""Models own their default search boxes and their Bouc-Wen shape.

The expected tables are the bounds `ParameterSpace.default` (piezo models, BoucWen)
and `oscillator_space` (HystereticOscillator) set before the models owned them,
written out as formulas.
"""

from types import SimpleNamespace
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxhyst as jh


RATE = 400.0


def _recording():
    t = np.arange(0.0, 3.0, 1 / RATE)
    u = 2.5 * np.sin(2 * np.pi * t) + 0.4 * np.sin(7 * t)
    y = 3e-5 * np.sin(2 * np.pi * t - 0.3) + 1e-6
    return jh.Recording(t, u, y)


RECORDING = _recording()
SU = float(np.max(np.abs(RECORDING.u)))
SY = float(np.max(np.abs(RECORDING.y)))
RU = float(np.sqrt(np.mean(RECORDING.u**2)))
RY = float(np.sqrt(np.mean(RECORDING.y**2)))
DURATION = RECORDING.duration

PIEZO = jh.PiezoBoucWen(0.3, 0.2, -0.4, 0.6, -0.2, 1.5)
CORRECTED = jh.CorrectedPiezoBoucWen.from_piezo(PIEZO, phi=0.01, eps=1e-3)
STAGE = jh.PiezoStage.from_piezo(PIEZO, natural_frequency=50.0, damping_ratio=0.4)
BOUC_WEN = jh.BoucWen(2.0, 0.3, 1.5, 1.0, 0.6, 0.2, 1.4)
OSCILLATOR = jh.HystereticOscillator.benchmark_truth()
STRUCTURAL = jh.StructuralBoucWen(3.0, 0.2, 1.0, 0.5, 0.3, 1.2)
EXTENDED = jh.ExtendedPiezo(0.3, 0.2, -0.4, 0.6, -0.2, 1.5)


def _piezo_table(gauge):
    bounds = {
        "k1": (-3 * SY / SU, 3 * SY / SU),
        "k2": (-5 * SY, 5 * SY),
        "A1": (-3 / SU, 3 / SU),
        "beta1": (-50 / SU, 50 / SU),
        "gamma1": (-50 / SU, 50 / SU),
        "n": (1.0, 3.0),
    }
    if gauge:
        del bounds["A1"]
    return bounds


def _check_space(space, template, bounds, log_scale):
    """`space` is exactly `ParameterSpace(template, bounds, log_scale=log_scale)`."""
    names = tuple(n for n in template.parameter_names if n in bounds)
    assert space.names == names
    np.testing.assert_array_equal(space.lower, [bounds[n][0] for n in names])
    np.testing.assert_array_equal(space.upper, [bounds[n][1] for n in names])
    assert space.log_scale == tuple(n in log_scale for n in names)
    for name, value in template.parameters().items():
        assert float(getattr(space.template, name)) == float(value), name


def test_data_scales_of_a_recording():
    scales = jh.DataScales.of(RECORDING)
    assert scales == jh.DataScales(
        input_peak=SU,
        output_peak=SY,
        input_rms=RU,
        output_rms=RY,
        duration=DURATION,
        sample_rate=RECORDING.sample_rate,
    )


def test_data_scales_reject_a_constant_input_or_output():
    t = np.arange(0.0, 1.0, 0.01)
    with pytest.raises(ValueError, match="a constant input or output cannot identify"):
        jh.DataScales.of(jh.Recording(t, np.sin(t), np.zeros_like(t)))
    # A Recording rejects a constant input itself; anything with .u and .y may not.
    flat = SimpleNamespace(
        u=np.zeros_like(t), y=np.sin(t), duration=0.99, sample_rate=100.0
    )
    with pytest.raises(ValueError, match=r"input_peak \(max\|u\|\) = 0"):
        jh.DataScales.of(flat)  # pyright: ignore[reportArgumentType]
    with pytest.raises(ValueError, match="duration"):
        jh.DataScales(1.0, 1.0, 1.0, 1.0, 0.0, 100.0)
    with pytest.raises(TypeError, match="expected a Recording"):
        jh.DataScales.of(4.0)  # pyright: ignore[reportArgumentType]


@pytest.mark.parametrize("gauge", [True, False])
def test_piezo_default_bounds(gauge):
    box = PIEZO.default_bounds(jh.DataScales.of(RECORDING), gauge=gauge)
    assert box.bounds == _piezo_table(gauge)
    assert box.log_scale == ()
    a1 = 1.0 / SU if gauge else float(PIEZO.A1)
    assert float(box.template.parameters()["A1"]) == a1
    space = jh.ParameterSpace.default(PIEZO, RECORDING, gauge=gauge)
    _check_space(space, PIEZO.replace(A1=a1), _piezo_table(gauge), ())


@pytest.mark.parametrize("gauge", [True, False])
def test_corrected_default_bounds_add_phi_and_eps(gauge):
    expected = _piezo_table(gauge)
    expected["phi"] = (-0.05 * DURATION, 0.05 * DURATION)
    expected["eps"] = (-2.0 / (SU * DURATION), 2.0 / (SU * DURATION))
    space = jh.ParameterSpace.default(CORRECTED, RECORDING, gauge=gauge)
    template = CORRECTED.replace(A1=1.0 / SU) if gauge else CORRECTED
    _check_space(space, template, expected, ())


@pytest.mark.parametrize("gauge", [True, False])
def test_stage_default_bounds_add_the_resonance(gauge):
    expected = _piezo_table(gauge)
    expected["natural_frequency"] = (
        2.0 / DURATION,
        0.5 * (0.5 * RECORDING.sample_rate),
    )
    expected["damping_ratio"] = (1e-3, 3.0)
    log = ("natural_frequency", "damping_ratio")
    box = STAGE.default_bounds(jh.DataScales.of(RECORDING), gauge=gauge)
    assert box.log_scale == log
    space = jh.ParameterSpace.default(STAGE, RECORDING, gauge=gauge)
    template = STAGE.replace(A1=1.0 / SU) if gauge else STAGE
    _check_space(space, template, expected, log)


@pytest.mark.parametrize("gauge", [True, False])
def test_bouc_wen_default_bounds_fix_d(gauge):
    expected = {
        "k": (1e-3 * SY / SU, 10 * SY / SU),
        "alpha": (0.0, 1.0),
        "A": (-3.0, 3.0),
        "beta": (-10 / SU, 10 / SU),
        "gamma": (-10 / SU, 10 / SU),
        "n": (1.0, 3.0),
    }
    space = jh.ParameterSpace.default(BOUC_WEN, RECORDING, gauge=gauge)
    _check_space(space, BOUC_WEN.replace(D=1.0), expected, ("k",))


@pytest.mark.parametrize("nu_free", [False, True])
def test_oscillator_default_bounds_are_oscillator_space(nu_free):
    k0 = RU / RY
    nyquist = 0.5 * RECORDING.sample_rate
    expected = {
        "mass": (k0 / (2 * np.pi * nyquist) ** 2, k0 / (2 * np.pi * 1.0) ** 2),
        "damping": (1e-5 * k0, 1.0 * k0),
        "stiffness": (1e-2 * k0, 10 * k0),
        "alpha": (1e-2 * k0, 10 * k0),
        "beta_gamma": (-5 / RY, 5 / RY),
        "beta_delta": (-5 / RY, 5 / RY),
    }
    if nu_free:
        expected["nu"] = (1.0, 3.0)
    log = ("mass", "damping", "stiffness", "alpha")
    space = jh.ParameterSpace.default(OSCILLATOR, RECORDING, nu_free=nu_free)
    _check_space(space, OSCILLATOR, expected, log)
    reference = jh.periodic.oscillator_space(OSCILLATOR, RECORDING, nu_free=nu_free)
    assert space.names == reference.names
    assert space.log_scale == reference.log_scale
    np.testing.assert_array_equal(space.lower, reference.lower)
    np.testing.assert_array_equal(space.upper, reference.upper)


def test_default_takes_scales_or_a_recording():
    by_scales = jh.ParameterSpace.default(STAGE, jh.DataScales.of(RECORDING))
    by_recording = jh.ParameterSpace.default(STAGE, RECORDING)
    assert by_scales.names == by_recording.names
    np.testing.assert_array_equal(by_scales.lower, by_recording.lower)
    np.testing.assert_array_equal(by_scales.upper, by_recording.upper)


class Tiny(jh.AbstractHysteresisModel):
    """A model with neither default bounds nor a Bouc-Wen shape."""

    k: jax.Array = eqx.field(converter=jnp.asarray)
    smoothing: jh.AbstractSmoothing = eqx.field(default_factory=jh.ExactSign)

    parameter_names: ClassVar[tuple[str, ...]] = ("k",)
    state_size: ClassVar[int] = 1

    def vector_field(self, t, state, drive):
        return jnp.stack([drive.udot])

    def output(self, t, state, drive):
        return self.k * state[0]


@pytest.mark.parametrize("model", [Tiny(1.0), STRUCTURAL, EXTENDED])
def test_models_without_default_bounds_say_so(model):
    name = type(model).__name__
    message = (
        rf"{name}.default_bounds: no default bounds for {name}; build "
        r"ParameterSpace\(template, bounds\) yourself"
    )
    with pytest.raises(TypeError, match=message):
        model.default_bounds(jh.DataScales.of(RECORDING))
    with pytest.raises(TypeError, match=message):
        jh.ParameterSpace.default(model, RECORDING)


def test_default_rejects_a_non_model():
    with pytest.raises(TypeError, match="template must be a jaxhyst model"):
        jh.ParameterSpace.default("piezo", RECORDING)  # pyright: ignore[reportArgumentType]


SHAPES = [
    (BOUC_WEN, ("A", "beta", "gamma", "n", "D"), (1.0, 0.6, 0.2, 1.4, 1.5)),
    (PIEZO, ("A1", "beta1", "gamma1", "n"), (-0.4, 0.6, -0.2, 1.5, 1.0)),
    (CORRECTED, ("A1", "beta1", "gamma1", "n"), (-0.4, 0.6, -0.2, 1.5, 1.0)),
    (STAGE, ("A1", "beta1", "gamma1", "n"), (-0.4, 0.6, -0.2, 1.5, 1.0)),
    (EXTENDED, ("A1", "beta1", "gamma1", "n"), (-0.4, 0.6, -0.2, 1.5, 1.0)),
    (STRUCTURAL, ("A", "beta", "gamma", "n"), (1.0, 0.5, 0.3, 1.2, 1.0)),
    (
        OSCILLATOR,
        ("alpha", "beta_gamma", "beta_delta", "nu"),
        (5e4, 800.0, -1100.0, 1.0, 1.0),
    ),
    (
        jh.synthetic.ConcealedTruth(PIEZO),
        ("A1", "beta1", "gamma1", "n"),
        (-0.4, 0.6, -0.2, 1.5, 1.0),
    ),
]


@pytest.mark.parametrize("model, names, values", SHAPES)
def test_bouc_wen_shape_traces(model, names, values):
    @eqx.filter_jit
    def traced(m):
        shape = m.bouc_wen_shape()
        return tuple(shape), jh.is_bibo_stable(*shape)

    shape = model.bouc_wen_shape()
    assert shape.names == names
    got, stable = traced(model)
    np.testing.assert_allclose([float(v) for v in got], values, rtol=1e-15)
    np.testing.assert_allclose([float(v) for v in shape], values, rtol=1e-15)
    assert bool(stable) == jh.bibo_stability(model).stable


@pytest.mark.parametrize("model, names, values", SHAPES)
def test_bibo_stability_speaks_the_models_names(model, names, values):
    report = jh.bibo_stability(model)
    a, b, g = names[:3]
    assert report.reason.startswith(f"{a}={values[0]:g}, {b}={values[1]:g}, {g}=")


def test_bibo_stability_verdicts():
    # A < 0 with beta - gamma > 0 and beta + gamma >= 0: stable.
    assert jh.bibo_stability(PIEZO)
    assert jh.bibo_stability(BOUC_WEN)
    assert not jh.bibo_stability(BOUC_WEN.replace(D=-1.0))
    report = jh.bibo_stability(PIEZO.replace(n=0.5))
    assert not report and report.reason.startswith("n=0.5 must be >= 1")
    report = jh.bibo_stability(OSCILLATOR.replace(nu=0.5))
    assert not report and report.reason.startswith("nu=0.5 must be >= 1")
    report = jh.bibo_stability(PIEZO.replace(A1=0.0))
    assert report.reason == "A1=0: the operator has no hysteresis"


def test_models_without_a_shape_say_so():
    with pytest.raises(TypeError, match="Tiny has no Bouc-Wen shape parameters"):
        Tiny(1.0).bouc_wen_shape()
    with pytest.raises(
        TypeError, match="bibo_stability: Tiny has no Bouc-Wen shape parameters"
    ):
        jh.bibo_stability(Tiny(1.0))


def test_search_box_holds_float_bounds():
    bounds = {"k1": (np.float32(-1), 2)}
    box = jh.identification.SearchBox(PIEZO, bounds, ["k1"])  # pyright: ignore[reportArgumentType]
    assert box.bounds == {"k1": (-1.0, 2.0)}
    assert type(box.bounds["k1"][0]) is float
    assert box.log_scale == ("k1",)
