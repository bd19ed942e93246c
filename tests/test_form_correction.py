"""The form-correction stage (`_form_corrections`): an effect adopted after others
stays a finding only if it fits the held-out samples better, beyond the resolution,
than the model without it corrected by a model-free function of the loop (what a
form of the earlier findings other than the catalogue's would change).

The refits are stand-ins whose outputs are set, so these tests pin the stage's
decisions without fitting anything; the held-out comparison is the engine's own
arithmetic with a set standard error."""

import math
import types

import jax
import numpy as np
import pytest
from helpers import validation

import jaxhyst as jh
import jaxhyst._diagnose._diagnose as engine
from jaxhyst._diagnose._residual_probes import excursion_probe


FAMILY = jh.families.StructuralFamily()
PINCHING, DRIFT = FAMILY.effect("pinching"), FAMILY.effect("drift")
BASE_FREE = ("k", "alpha", "A", "beta", "gamma", "n")
PINCHED = jh.StructuralBoucWen(10.0, 0.05, 1.0, 0.3, 0.2, 1.5).replace(pinch=0.5)
BOTH = PINCHED.replace(trend=0.2)

N = 1200
T = np.arange(N, dtype=float)
# A ladder: four levels of three cycles each (100 samples a cycle), as cyclic tests.
X = np.sin(2 * np.pi * T / 100) * (0.25 + 0.25 * (T // 300))
RISING = np.diff(X, prepend=X[0]) >= 0
HOLD = (T // 100) % 3 == 2  # one cycle of each level held out
SIGMA = 0.01
RECORDING = jh.Recording(T, X, np.zeros(N), name="stand-in")
# A mismatch that follows the loop (a pinching written in another law) and a slow
# trend that does not.
LOOP = 0.3 * np.where(RISING, 1.0, -1.0) * np.exp(-((X / 0.3) ** 2))
TREND = 0.2 * (T / N - 0.5)


def _finding(effect: str) -> jh.Finding:
    return jh.Finding(effect, "", "", 1.0, {}, {}, {}, validation())


@pytest.fixture
def stage(monkeypatch):
    """`run(y, with_both, without_second, *, first, second)`: the stage on two
    findings, the stand-in model with both answering `with_both` and the refit
    without the second answering `without_second` (outputs; the record is `y`)."""
    refitted = []

    def run(y, with_both, without_second, *, first=PINCHING, second=DRIFT, se=None):
        def refit(ctx, state, start, free, **_):
            refitted.append(tuple(free))
            return start

        def predict(ctx, model):
            return with_both if second.is_on(model) else without_second

        def comparison(ctx, state, kept, other):
            # White noise of SIGMA: the standard error of the MSE difference of two
            # fits whose outputs differ by `change` (`NoiseModel.resolution`).
            change = float(np.sqrt(np.mean((kept - other)[HOLD] ** 2)))
            return (
                float(np.mean((y - kept)[HOLD] ** 2)),
                float(np.mean((y - other)[HOLD] ** 2)),
                2 * SIGMA * change / math.sqrt(HOLD.sum()) if se is None else se,
            )

        monkeypatch.setattr(engine, "_refit", refit)
        monkeypatch.setattr(engine, "_predict", predict)
        monkeypatch.setattr(engine, "_heldout_comparison", comparison)
        state = engine._State(
            current=BOTH,
            predicted=with_both,
            free=BASE_FREE + first.parameters + second.parameters,
            findings=(_finding(first.name), _finding(second.name)),
        )
        ctx = types.SimpleNamespace(
            family=FAMILY,
            policy=jh.families.AdoptionPolicy(),
            progress=types.SimpleNamespace(say=lambda message: None),
            key=jax.random.key(0),
            recording=RECORDING,
            y=y,
            fit_mask=~HOLD,
            hold_mask=HOLD,
        )
        return engine._form_corrections(ctx, state), refitted  # pyright: ignore[reportArgumentType]

    return run


def _noise(seed: int = 0) -> np.ndarray:
    return SIGMA * np.random.default_rng(seed).standard_normal(N)


def test_a_later_effect_that_only_takes_up_a_loop_form_difference_is_not_named(stage):
    # The record: the pinched model's output plus a loop-shaped form difference.
    # A drift took up a little of it (the part that happens to trend); the loop
    # correction of the model without the drift takes up all of it.
    y = LOOP + _noise()
    with_drift = 0.1 * LOOP
    state, refitted = stage(y, with_drift, np.zeros(N))
    assert state.adopted == ("pinching",)
    assert refitted == [BASE_FREE + PINCHING.parameters]
    assert not DRIFT.is_on(state.current)
    assert state.free == BASE_FREE + PINCHING.parameters
    (said,) = state.ambiguities
    assert said.undecided == ("drift",)
    assert said.statement.startswith(
        "drift may be present, or the form of pinching differs from the catalogue's"
    )
    assert "largest excursion" in said.statement or "direction" in said.statement
    assert state.steps[-1].label == (
        "drift dropped (a form correction of pinching fits as well)"
    )
    # The advice compares the model with the drift and the one without it.
    (contrast,) = state.contrasts
    assert contrast.separates == ("drift",) and contrast.kept is BOTH


def test_a_later_effect_the_loop_cannot_stand_for_stays(stage):
    # A true drift: the model without it leaves a trend, which a function of the
    # loop's position, direction and excursion predicts on held-out cycles only
    # level by level (the trend within a level is left, many noise sigmas).
    y = TREND + _noise()
    state, _ = stage(y, np.asarray(TREND), np.zeros(N))
    assert state.adopted == ("pinching", "drift")
    assert state.current is BOTH and state.ambiguities == ()


def test_a_later_effect_better_than_the_correction_by_the_resolution_stays(stage):
    # A loop-shaped later effect that its model fits exactly, where the bins of the
    # correction leave part of it: better by far more than the resolution.
    y = LOOP + _noise()
    state, _ = stage(y, LOOP.copy(), np.zeros(N))
    assert state.adopted == ("pinching", "drift")


@pytest.mark.parametrize("ahead, named", [(2.0, True), (0.5, False)])
def test_a_later_effect_needs_to_be_ahead_of_the_correction_by_a_standard_error(
    stage, ahead, named
):
    # A later effect that fits the loop-shaped mismatch exactly, judged with a
    # standard error that puts it `ahead` standard errors of the difference in
    # front of the correction (whose bins leave part of the mismatch): ahead by
    # more than one it stays, though below the resolution of 3 (the held-out data
    # favour it over a correction with far more freedom); by less, it is not named.
    y = LOOP + _noise()
    corrected = min(
        (
            engine.bin_prediction(p.labels, y, ~HOLD)
            for p in FAMILY.form_probes(RECORDING)
        ),
        key=lambda c: float(np.mean((y - c)[HOLD] ** 2)),
    )
    gap = float(np.mean((y - corrected)[HOLD] ** 2) - np.mean((y - LOOP)[HOLD] ** 2))
    assert gap > 0
    state, _ = stage(y, LOOP.copy(), np.zeros(N), se=gap / ahead)
    assert (state.adopted == ("pinching", "drift")) is named


def test_after_effects_whose_forms_do_not_show_in_loops_nothing_is_judged(stage):
    # A drift named first cannot take another form that a loop correction stands
    # for: the pinching after it is not judged against one.
    y = LOOP + _noise()
    state, refitted = stage(y, 0.1 * LOOP, np.zeros(N), first=DRIFT, second=PINCHING)
    assert refitted == [] and state.adopted == ("drift", "pinching")


def test_the_stage_is_off_with_the_policy(stage, monkeypatch):
    policy = jh.families.AdoptionPolicy(form_correction=False)
    monkeypatch.setattr(
        engine, "_against_form_correction", lambda *a: pytest.fail("judged")
    )
    ctx = types.SimpleNamespace(policy=policy)
    state = engine._State(
        current=BOTH,
        predicted=np.zeros(N),
        free=(),
        findings=(_finding("pinching"), _finding("drift")),
    )
    assert engine._form_corrections(ctx, state) is state  # pyright: ignore[reportArgumentType]


def test_the_excursion_probe_bins_the_loop_by_its_position_and_reach():
    labels = excursion_probe(RECORDING).labels
    assert labels.shape == (N,) and labels.min() >= 0
    # The same place in the loop at the same reach shares a bin, cycle after cycle
    # (at a constant amplitude the reach is constant after the first cycle).
    steady = jh.Recording(T, np.sin(2 * np.pi * T / 100), np.zeros(N))
    steady_labels = excursion_probe(steady).labels
    np.testing.assert_array_equal(steady_labels[200:300], steady_labels[300:400])
    assert math.isfinite(float(labels.sum()))
