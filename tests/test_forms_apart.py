"""The forms stage (`_forms_apart`): a finding whose effect has several forms on is
refitted in each form alone; a form alone within the resolution of the forms
together takes their place, and forms the record cannot tell apart are said.

The refits and the held-out comparison are replaced by stand-ins with set held-out
errors, so these tests pin the stage's decisions without fitting anything."""

import math
import types

import jax
import numpy as np
import pytest
from helpers import validation

import jaxhyst as jh
import jaxhyst._diagnose._diagnose as engine


FAMILY = jh.families.StructuralFamily()
DEGRADATION = FAMILY.effect("degradation")
BASE_FREE = ("k", "alpha", "A", "beta", "gamma", "n")
BOTH = jh.StructuralBoucWen(10.0, 0.05, 1.0, 0.3, 0.2, 1.5).replace(
    strength_degradation=0.1,
    stiffness_degradation=0.05,
    peak_strength_degradation=0.2,
    peak_stiffness_degradation=0.1,
)


def _output(mse: float) -> np.ndarray:
    """A stand-in output whose MSE against a zero record is `mse`."""
    return np.full(4, math.sqrt(mse))


@pytest.fixture
def stage(monkeypatch):
    """`run(heldout_mse, *, se=1.0, policy=...)`: the stage on one degradation
    finding with both its forms on, the stand-in refit of each form alone answering
    with `heldout_mse[form]` and the forms together with `heldout_mse["together"]`;
    returns the state and the free parameters of each refit."""
    refits: dict[str, tuple[str, ...]] = {}

    def run(heldout_mse, *, se=1.0, policy=jh.families.AdoptionPolicy()):
        def refit(ctx, state, start, free, **_):
            (form,) = DEGRADATION.forms_on(start)
            refits[form] = tuple(free)
            return start

        def predict(ctx, model):
            (form,) = DEGRADATION.forms_on(model)
            return _output(heldout_mse[form])

        def comparison(ctx, state, kept, other):
            return float(np.mean(kept**2)), float(np.mean(other**2)), se

        monkeypatch.setattr(engine, "_refit", refit)
        monkeypatch.setattr(engine, "_predict", predict)
        monkeypatch.setattr(engine, "_heldout_comparison", comparison)
        finding = jh.Finding("degradation", "", "", 1.0, {}, {}, {}, validation())
        state = engine._State(
            current=BOTH,
            predicted=_output(heldout_mse["together"]),
            free=BASE_FREE + DEGRADATION.parameters,
            findings=(finding,),
        )
        ctx = types.SimpleNamespace(
            family=FAMILY,
            policy=policy,
            progress=types.SimpleNamespace(say=lambda message: None),
            key=jax.random.key(0),
            y=np.zeros(4),
            hold_mask=np.ones(4, bool),
        )
        return engine._forms_apart(ctx, state), refits  # pyright: ignore[reportArgumentType]

    return run


def test_a_form_alone_within_the_resolution_takes_the_forms_place(stage):
    state, refits = stage({"together": 10.0, "energy": 11.0, "peak_excursion": 30.0})
    # Each form refitted alone, the other form's parameters held.
    assert set(refits) == {"energy", "peak_excursion"}
    assert set(refits["energy"]) == set(BASE_FREE) | {
        "strength_degradation",
        "stiffness_degradation",
    }
    assert DEGRADATION.forms_on(state.current) == ("energy",)
    assert "peak_strength_degradation" not in state.free
    assert state.steps[-1].label == "degradation in its energy form alone"
    assert not any("cannot tell the forms" in a.statement for a in state.ambiguities)


def test_forms_the_record_cannot_tell_apart_are_said(stage):
    state, _ = stage({"together": 10.0, "energy": 11.5, "peak_excursion": 11.0}, se=1.0)
    assert DEGRADATION.forms_on(state.current) == ("peak_excursion",)
    (said,) = (
        a
        for a in state.ambiguities
        if "cannot tell the forms of degradation" in a.statement
    )
    assert "keeps peak_excursion" in said.statement
    assert said.undecided == ()


def test_forms_each_needed_stay_together(stage):
    state, refits = stage({"together": 10.0, "energy": 14.0, "peak_excursion": 20.0})
    assert set(refits) == {"energy", "peak_excursion"}
    assert state.current is BOTH
    assert state.free == BASE_FREE + DEGRADATION.parameters
    assert state.ambiguities == ()


def test_a_form_alone_better_than_together_is_kept_even_when_far_better(stage):
    state, _ = stage({"together": 10.0, "energy": 4.0, "peak_excursion": 20.0})
    assert DEGRADATION.forms_on(state.current) == ("energy",)


def test_the_stage_is_off_with_the_policy(stage):
    policy = jh.families.AdoptionPolicy(forms_apart=False)
    state, refits = stage(
        {"together": 10.0, "energy": 10.0, "peak_excursion": 30.0}, policy=policy
    )
    assert refits == {} and state.current is BOTH


def test_an_effect_in_one_form_alone_helper_holds_the_others():
    model, held = DEGRADATION.alone(BOTH, "peak_excursion")
    assert DEGRADATION.forms_on(model) == ("peak_excursion",)
    assert set(held) == {"strength_degradation", "stiffness_degradation"}
    assert model.peak_strength_degradation == BOTH.peak_strength_degradation
    assert model.strength_degradation == 0.0


def test_what_was_said_of_a_dropped_findings_forms_goes_with_it(stage, monkeypatch):
    # A finding dropped afterwards as undetermined: the statement that the record
    # cannot tell its forms apart is no longer about a finding; other statements
    # stay.
    state, _ = stage({"together": 10.0, "energy": 11.5, "peak_excursion": 11.0})
    assert any("cannot tell the forms" in a.statement for a in state.ambiguities)
    other = engine.Ambiguity("cannot tell whether drift is present", ("drift",))
    base = types.SimpleNamespace(model=DEGRADATION.switch_off(BOTH))
    state = engine._State(
        current=state.current,
        predicted=state.predicted,
        free=state.free,
        findings=state.findings,
        ambiguities=(other, *state.ambiguities),
        steps=(base, *state.steps),
    )
    monkeypatch.setattr(engine, "_predict", lambda ctx, model: _output(10.0))
    ctx = types.SimpleNamespace(
        family=FAMILY,
        progress=types.SimpleNamespace(say=lambda message: None),
        y=np.zeros(4),
        hold_mask=np.ones(4, bool),
    )
    dropped = engine._without(ctx, state, {"degradation": "its gains within 1 sigma"})  # pyright: ignore[reportArgumentType]
    assert dropped.findings == ()
    assert dropped.ambiguities[0] is other
    assert not any("cannot tell the forms" in a.statement for a in dropped.ambiguities)
    assert "does not determine" in dropped.ambiguities[-1].statement
