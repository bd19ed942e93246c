"""A named effect must be determined by the record: an effect whose defining
parameters have no standard error below their size is not a finding."""

import dataclasses
import math
import types

import numpy as np
from helpers import validation

import jaxhyst as jh
import jaxhyst._diagnose._diagnose as engine
from jaxhyst._diagnose._effects.base import determined


PIEZO = jh.families.PiezoFamily()
STRUCTURAL = jh.families.StructuralFamily()


def test_a_parameter_is_determined_by_an_error_below_its_size():
    assert determined(1.0, 0.5)
    assert determined(-1.0, 0.5)
    assert not determined(1.0, 2.0)
    assert not determined(1.0, math.nan)
    assert not determined(1.0, math.inf)
    assert not determined(0.0, 0.0)


def test_one_determined_gain_determines_an_effect():
    drift = STRUCTURAL.effect("drift")
    values = {"offset": 0.5, "trend": 1e-4, "curvature": 0.0, "wander": 0.0}
    errors = {"offset": 0.01, "trend": 1e-3, "curvature": 1.0, "wander": math.nan}
    assert drift.undetermined(values, errors, {}) == ()
    errors["offset"] = 0.8
    assert drift.undetermined(values, errors, {}) == drift.gains


def test_gains_that_trade_off_are_determined_together():
    """A delay and a lead network, each within 1 standard error of zero, whose
    errors are strongly anticorrelated: their sum, the time shift, is determined.
    The same values with the errors positively correlated determine nothing."""
    bias = PIEZO.effect("input_bias")
    values = {"phi": 1.0, "input_lead": 1.0, "input_time": 0.01}
    errors = {"phi": 1.5, "input_lead": 1.5, "input_time": 0.1}

    def correlated(rho):
        return {"phi": {"input_lead": rho}, "input_lead": {"phi": rho}}

    assert not determined(values["phi"], errors["phi"])
    assert bias.undetermined(values, errors, correlated(-0.95)) == ()
    assert bias.undetermined(values, errors, correlated(0.95)) == bias.gains
    assert bias.undetermined(values, errors, {}) == bias.gains


def test_a_resonance_is_determined_by_its_frequency():
    dynamics = PIEZO.effect("dynamics")
    values = {"natural_frequency": 850.0, "damping_ratio": 0.2}
    assert dynamics.undetermined(values, {"natural_frequency": 30.0}, {}) == ()
    undetermined = {"natural_frequency": 2e5, "damping_ratio": 200.0}
    assert dynamics.undetermined(values, undetermined, {}) == ("natural_frequency",)


def test_an_undetermined_finding_leaves_the_model_and_is_said(monkeypatch):
    monkeypatch.setattr(engine, "_predict", lambda ctx, model: np.zeros(4))
    drift = STRUCTURAL.effect("drift")
    model = jh.StructuralBoucWen(10.0, 0.05, 1.0, 0.3, 0.2, 1.5).replace(
        offset=0.5, trend=0.01, yield_skew=0.1
    )
    errors = {"asymmetry": 0.01, "drift": 5.0}  # drift: no value above 5.0
    found = tuple(
        dataclasses.replace(
            jh.Finding(name, "", "", 1.0, {}, {}, {}, validation()),
            final_parameters=STRUCTURAL.effect(name).values(model),
            standard_errors=dict.fromkeys(
                STRUCTURAL.effect(name).parameters, errors[name]
            ),
            units=dict.fromkeys(STRUCTURAL.effect(name).parameters, "kN"),
        )
        for name in ("asymmetry", "drift")
    )
    ctx = types.SimpleNamespace(
        family=STRUCTURAL,
        progress=types.SimpleNamespace(say=lambda message: None),
        y=np.ones(4),
        hold_mask=np.ones(4, bool),
    )
    free = (*STRUCTURAL.base_free, "yield_skew", "stiffness_skew", *drift.parameters)
    state = engine._State(
        current=model, predicted=np.ones(4), free=free, findings=found
    )
    dropped = engine._undetermined(ctx, state.findings, {})  # pyright: ignore[reportArgumentType]
    assert list(dropped) == ["drift"]
    assert "offset = 0 ± 5 kN" in dropped["drift"]
    state = engine._without(ctx, state, dropped)  # pyright: ignore[reportArgumentType]
    assert state.adopted == ("asymmetry",)
    assert not drift.is_on(state.current)
    assert float(state.current.yield_skew) == 0.1
    assert not set(drift.parameters) & set(state.free)
    (said,) = state.ambiguities
    assert said.undecided == ("drift",)
    assert "does not determine" in said.statement
    assert state.steps[-1].label.startswith("drift dropped")
    # With nothing left named, the model is the base fit again (its first step).
    base = jh.StructuralBoucWen(9.0, 0.05, 1.0, 0.3, 0.2, 1.5)
    first = engine.DiagnosisStep("bouc-wen fitted", 1.0, 1.0, base)
    only_drift = dataclasses.replace(state, findings=found[1:], steps=(first,))
    state = engine._without(ctx, only_drift, dropped)  # pyright: ignore[reportArgumentType]
    assert state.adopted == () and state.current is base
