"""Models answer for themselves: their parameter names (from their fields), the solver
they are simulated with, what makes their output lag the drive (compensation), and
their exports (C, OpenSees). Nothing outside the model classes asks a model its type.

The expected parameter tuples are the ones each model listed by hand before they
were derived from the fields: model files, exports and fits depend on their order.
"""

import dataclasses
import inspect
from typing import ClassVar

import equinox as eqx
import numpy as np
import pytest
from jaxtyping import Array, Float

import jaxhyst as jh
from jaxhyst._diagnose._families import DamperFamily, StructuralFamily
from jaxhyst._model_files import model_file_dict
from jaxhyst._models import (
    base,
    bouc_wen,
    damper,
    damper_extended,
    extended,
    oscillator,
    structural,
)
from jaxhyst._models.base import AbstractDrive, StageDynamics, as_parameter
from jaxhyst._models.damper import AbstractDamperDrive
from jaxhyst._models.damper_extended import LaggedCommandDrive


PIEZO_NAMES = ("k1", "k2", "A1", "beta1", "gamma1", "n")
DAMPER_NAMES = ("c0", "k0", "x0", "alpha", "f0", "A", "beta", "gamma", "n")
PARAMETER_NAMES = {
    jh.BoucWen: ("k", "alpha", "D", "A", "beta", "gamma", "n"),
    jh.PiezoBoucWen: PIEZO_NAMES,
    jh.CorrectedPiezoBoucWen: (*PIEZO_NAMES, "phi", "eps"),
    jh.PiezoStage: (*PIEZO_NAMES, "natural_frequency", "damping_ratio"),
    jh.HystereticOscillator: (
        "mass",
        "damping",
        "stiffness",
        "alpha",
        "beta_gamma",
        "beta_delta",
        "nu",
    ),
    jh.StructuralBoucWen: (
        "k",
        "alpha",
        "A",
        "beta",
        "gamma",
        "n",
        "strength_degradation",
        "stiffness_degradation",
        "peak_strength_degradation",
        "peak_stiffness_degradation",
        "pinch",
        "pinch_shift",
        "pinch_width",
        "pinch_rate",
        "slip_length",
        "slip_window",
        "yield_skew",
        "stiffness_skew",
        "offset",
        "trend",
        "curvature",
        "wander",
    ),
    jh.ExtendedPiezo: (
        *PIEZO_NAMES,
        "eps",
        "quad",
        "cubic",
        "skew",
        "phi",
        "input_lead",
        "input_time",
        "rate_gain",
        "viscous",
        "rate_amplitude",
        "viscous_time",
        "creep_faster",
        "creep_fast",
        "creep_slow",
        "creep_slower",
        "offset",
        "trend",
        "curvature",
        "wander",
        "natural_frequency",
        "damping_ratio",
    ),
    jh.BoucWenDamper: DAMPER_NAMES,
    jh.SpencerDamper: (
        "c0a",
        "c0b",
        "k0",
        "c1a",
        "c1b",
        "k1",
        "x0",
        "alpha_a",
        "alpha_b",
        "A",
        "beta",
        "gamma",
        "n",
        "eta",
    ),
    jh.ExtendedDamper: (
        *DAMPER_NAMES,
        "field_alpha",
        "field_damping",
        "field_knee",
        "command_lag",
        "field_lag",
        "rolloff",
        "skew",
        "damping_skew",
        *(f"offset{k}" for k in range(1, 27)),
    ),
}
SETTING_NAMES = {
    jh.StructuralBoucWen: (
        "pinch_lambda",
        "energy_scale",
        "displacement_scale",
        "force_scale",
        "time_center",
        "time_scale",
        "slip_from_yield",
    ),
    jh.ExtendedPiezo: (
        "input_center",
        "input_scale",
        "rate_scale",
        "time_center",
        "time_scale",
        "creep_times",
        "dynamic",
    ),
    jh.ExtendedDamper: ("command_scale", "damping_scale", "time_center", "time_scale"),
}

T = np.arange(0.0, 2.0, 1 / 500.0)
U = 2 - 1.8 * np.cos(2 * np.pi * 2.0 * T)
RECORDING = jh.Recording(T, U, 3e-5 * np.sin(2 * np.pi * 2 * T - 0.3))
DAMPER_RECORDING = jh.Recording(
    T,
    0.01 * U,
    100 * np.sin(2 * np.pi * 2 * T),
    more_inputs={"command": 1 + 0.5 * np.sin(2 * np.pi * 0.7 * T)},
)

PAPER = jh.PiezoBoucWen.paper_table4()
SHIFTED = jh.CorrectedPiezoBoucWen.from_piezo(PAPER, phi=0.01, eps=1e-3)
STAGE = jh.PiezoStage.from_piezo(PAPER, natural_frequency=50.0, damping_ratio=0.4)
EXTENDED = jh.ExtendedPiezo.around(PAPER, RECORDING.input_path()).replace(
    trend=0.05 * PAPER.k1
)
BOUC_WEN = jh.BoucWen(2.0, 0.3, 1.5, 1.0, 0.6, 0.2, 1.4)
STRUCTURAL = jh.StructuralBoucWen(3.0, 0.2, 1.0, 0.5, 0.3, 1.2)
BASE_DAMPER = jh.BoucWenDamper(10.0, 5.0, 0.0, 50.0, 0.1, 1.0, 300.0, 300.0, 2.0)
MODELS = [
    BOUC_WEN,
    PAPER,
    SHIFTED,
    STAGE,
    jh.HystereticOscillator.benchmark_truth(),
    STRUCTURAL,
    EXTENDED,
    BASE_DAMPER,
    jh.SpencerDamper.spencer_1997(),
    jh.ExtendedDamper.around(BASE_DAMPER, DAMPER_RECORDING.input_path(), 100.0),
]


def _ids(model):
    return type(model).__name__


def test_every_model_class_is_covered():
    assert {type(m) for m in MODELS} == set(PARAMETER_NAMES)


# ------------------------------------------------------------------ parameter names


@pytest.mark.parametrize("cls", list(PARAMETER_NAMES), ids=lambda c: c.__name__)
def test_parameter_names_are_the_positional_fields_in_the_old_order(cls):
    assert cls.parameter_names == PARAMETER_NAMES[cls]
    positional = tuple(f.name for f in dataclasses.fields(cls) if not f.kw_only)
    assert cls.parameter_names == positional
    # Read from the class and from a model alike.
    model = next(m for m in MODELS if type(m) is cls)
    assert model.parameter_names == PARAMETER_NAMES[cls]
    assert tuple(model.parameters()) == PARAMETER_NAMES[cls]


@pytest.mark.parametrize("cls", list(PARAMETER_NAMES), ids=lambda c: c.__name__)
def test_setting_names_are_the_fields_a_model_file_stores(cls):
    assert cls.setting_names == SETTING_NAMES.get(cls, ())
    model = next(m for m in MODELS if type(m) is cls)
    fields = model_file_dict(model)["model"]["fields"]
    assert sorted(fields) == sorted(cls.setting_names)


class _Spring(jh.AbstractHysteresisModel[jh.Drive]):
    """A model that lists neither its parameters nor its settings."""

    k: Float[Array, ""] = eqx.field(converter=as_parameter)
    c: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    scale: Float[Array, ""] = eqx.field(
        converter=as_parameter, default=1.0, kw_only=True
    )
    smoothing: jh.AbstractSmoothing = eqx.field(
        default_factory=jh.ExactSign, kw_only=True
    )

    state_size: ClassVar[int] = 1

    def vector_field(self, t, state, drive):
        return drive.udot[None] / self.scale

    def output(self, t, state, drive):
        return self.k * state[0] + self.c * drive.udot


def test_a_new_model_derives_its_names_from_its_fields():
    assert _Spring.parameter_names == ("k", "c")
    assert _Spring.setting_names == ("scale",)
    spring = _Spring(2.0)
    assert {k: float(v) for k, v in spring.parameters().items()} == {"k": 2.0, "c": 0.0}
    assert float(spring.replace(c=3.0).c) == 3.0
    # The defaults: one RK4 step per sample, nothing lags, no exports.
    assert spring.default_solver(RECORDING) == jh.RK4()
    assert spring.lag_reason() is None
    assert spring.stage_dynamics() is None
    assert spring.time_shift() == 0.0
    assert spring.quasi_static() is spring
    assert not spring.has_opensees_material


# -------------------------------------------------------------------------- solvers


def _expected_solver(model):
    if isinstance(model, jh.PiezoStage):
        return jh.RK4(substeps=4)
    if isinstance(model, jh.BoucWen | jh.StructuralBoucWen):
        return StructuralFamily().solver(RECORDING)
    if isinstance(model, jh.ExtendedDamper):
        return DamperFamily().solver(DAMPER_RECORDING)
    if isinstance(model, jh.BoucWenDamper | jh.SpencerDamper):
        substeps = model.recommended_substeps(DAMPER_RECORDING.input_path())
        return jh.RK4(substeps=substeps)
    return jh.RK4()


@pytest.mark.parametrize("model", MODELS, ids=_ids)
def test_each_model_answers_its_default_solver(model):
    damper_model = "Damper" in type(model).__name__
    recording = DAMPER_RECORDING if damper_model else RECORDING
    expected = _expected_solver(model)
    assert model.default_solver(recording) == expected
    assert jh.default_solver(model, recording) == expected


def test_the_stiff_models_get_substeps():
    assert STAGE.default_solver(RECORDING).substeps == 4
    spencer = jh.SpencerDamper.spencer_1997()
    assert spencer.default_solver(DAMPER_RECORDING).substeps > 1


# --------------------------------------------------------------------- compensation


def _quasi_static_parameters(model):
    return {k: float(v) for k, v in model.quasi_static().parameters().items()}


def test_models_without_a_lag_answer_none():
    for model in (
        PAPER,
        BOUC_WEN,
        STRUCTURAL,
        EXTENDED,
        SHIFTED.replace(phi=0.0),
        BASE_DAMPER,
    ):
        assert model.lag_reason() is None
        assert model.time_shift() == 0.0
        assert model.stage_dynamics() is None
    assert PAPER.quasi_static() is PAPER
    assert EXTENDED.quasi_static().parameters().keys() == EXTENDED.parameters().keys()


def test_a_time_shift_answers_for_itself():
    assert SHIFTED.lag_reason() == (
        "CorrectedPiezoBoucWen with phi = 0.01 s reads the drive shifted in time "
        "(V(t) = u(t + phi)), not at the present sample"
    )
    assert SHIFTED.time_shift() == pytest.approx(0.01, rel=1e-15)
    assert SHIFTED.stage_dynamics() is None
    static = SHIFTED.quasi_static()
    assert type(static) is jh.CorrectedPiezoBoucWen and float(static.phi) == 0.0
    assert float(static.eps) == float(SHIFTED.eps)


def test_a_stage_answers_for_itself():
    assert STAGE.lag_reason() == (
        "PiezoStage's output is the position of a mass-spring-damper, which does "
        "not respond to the present drive within one sample"
    )
    assert STAGE.time_shift() == 0.0
    stage = STAGE.stage_dynamics()
    assert isinstance(stage, StageDynamics)
    assert stage.omega == 2 * np.pi * 50.0 and stage.zeta == 0.4
    np.testing.assert_array_equal(stage.drift(T[:4]), np.zeros(4))
    static = STAGE.quasi_static()
    assert type(static) is jh.PiezoBoucWen
    assert _quasi_static_parameters(STAGE) == {
        n: float(getattr(STAGE, n)) for n in PIEZO_NAMES
    }


def test_the_extended_piezo_answers_with_its_effects():
    dynamic = EXTENDED.with_dynamics(20.0, 0.4)
    assert dynamic.lag_reason() == (
        "this ExtendedPiezo has stage dynamics (inertia and damping)"
    )
    stage = dynamic.stage_dynamics()
    assert stage is not None
    assert (stage.omega, stage.zeta) == (2 * np.pi * 20.0, 0.4)
    np.testing.assert_array_equal(stage.drift(T[:4]), np.asarray(dynamic.drift(T[:4])))
    assert not dynamic.quasi_static().dynamic
    both = dynamic.replace(phi=-0.02)
    # The time shift is named first.
    assert both.lag_reason() == (
        "ExtendedPiezo with phi = -0.02 s reads the drive shifted in time "
        "(V(t) = u(t + phi)), not at the present sample"
    )
    assert both.time_shift() == pytest.approx(-0.02, rel=1e-15)
    static = both.quasi_static()
    assert float(static.phi) == 0.0 and not static.dynamic
    assert float(static.trend) == float(both.trend)


# ------------------------------------------------------------------------- exports


def test_c_export_parameters():
    expected = {n: float(getattr(PAPER, n)) for n in PIEZO_NAMES}
    assert PAPER.c_export_parameters() == {**expected, "eps": 0.0}
    at_zero = SHIFTED.replace(phi=0.0)
    assert at_zero.c_export_parameters() == {**expected, "eps": float(SHIFTED.eps)}
    with pytest.raises(ValueError, match="phi = 0.01 s shifts the drive in time"):
        SHIFTED.c_export_parameters()
    for model in MODELS:
        if type(model) in (jh.PiezoBoucWen, jh.CorrectedPiezoBoucWen):
            continue
        name = type(model).__name__
        with pytest.raises(ValueError, match=f"export_c: {name} has no C export"):
            model.c_export_parameters()


@pytest.mark.parametrize("model", MODELS, ids=_ids)
def test_opensees_models(model):
    exported = isinstance(model, jh.BoucWen | jh.StructuralBoucWen)
    assert model.has_opensees_material == exported
    if not exported:
        with pytest.raises(TypeError, match="StructuralBoucWen or BoucWen"):
            model.opensees_model()
        return
    structural_model = model.opensees_model()
    assert type(structural_model) is jh.StructuralBoucWen
    if isinstance(model, jh.BoucWen):
        converted = jh.StructuralBoucWen.from_bouc_wen(model)
        assert structural_model.parameters().keys() == converted.parameters().keys()
        for name, value in converted.parameters().items():
            assert float(getattr(structural_model, name)) == float(value), name
    else:
        assert structural_model is model


def test_opensees_parameters_are_the_models_fields():
    model = jh.StructuralBoucWen.around(STRUCTURAL, RECORDING.input_path(), 2.0)
    values = model.opensees_parameters()
    names = (*jh.StructuralBoucWen.parameter_names, "energy_scale", "pinch_lambda")
    assert tuple(values) == names
    for name in names:
        assert values[name] == float(getattr(model, name)), name
        assert type(values[name]) is float
    single = model.astype(np.float32).opensees_parameters()
    assert single["pinch_shift"] == 0.1  # the float32's shortest decimal


def test_the_opensees_export_reads_every_structural_parameter():
    # Every parameter changes the material (its arguments, or what it says it
    # drops) in one of the regimes it matters in: a parameter the model gains is
    # either mapped or reported dropped, never silently left out.
    regimes = (
        STRUCTURAL,
        STRUCTURAL.replace(pinch=0.3),
        STRUCTURAL.replace(slip_length=0.1),
    )
    for name in jh.StructuralBoucWen.parameter_names:
        changed = False
        for model in regimes:
            value = float(getattr(model, name))
            moved = model.replace(**{name: 1.5 * value + 0.1})
            before = jh.opensees_material(model).to_dict()
            after = jh.opensees_material(moved).to_dict()
            changed = changed or before != after
        assert changed, f"{name} does not reach the OpenSees material"


# ---------------------------------------------------------- abstract-or-final classes


def _module_classes():
    modules = (
        base,
        bouc_wen,
        damper,
        damper_extended,
        extended,
        oscillator,
        structural,
    )
    return {
        cls
        for module in modules
        for _, cls in inspect.getmembers(module, inspect.isclass)
        if issubclass(cls, eqx.Module) and cls.__module__.startswith("jaxhyst._models")
    }


def test_no_concrete_model_or_drive_class_is_subclassed():
    classes = _module_classes()
    for parent in classes:
        if parent.__name__.startswith("Abstract"):
            continue
        children = [
            c.__name__ for c in classes if c is not parent and parent in c.__mro__
        ]
        assert not children, (
            f"{parent.__name__} is concrete and subclassed by {children}"
        )


def test_drives_derive_from_the_abstract_drive():
    for drive in (jh.Drive, jh.ShiftedDrive, jh.DamperDrive, LaggedCommandDrive):
        assert issubclass(drive, AbstractDrive)
    for drive in (jh.DamperDrive, LaggedCommandDrive):
        assert issubclass(drive, AbstractDamperDrive)
    lagged = LaggedCommandDrive(*(np.float64(v) for v in range(6)))
    assert (float(lagged.x), float(lagged.xdot), float(lagged.v)) == (0.0, 1.0, 2.0)


def test_from_piezo_refuses_another_model():
    with pytest.raises(TypeError, match="base must be a PiezoBoucWen, got PiezoStage"):
        jh.CorrectedPiezoBoucWen.from_piezo(STAGE)
