"""The rival stage (`_rivals`): every finding is refitted against the other effects
of the catalogue (those that passed validation, and those that failed it or were
never refitted); a rival better beyond the resolution replaces it, and among
effects the record cannot tell apart the fit keeps the one with the lowest held-out
error.

The refits and the held-out comparison are replaced by stand-ins with set held-out
errors, so these tests pin the stage's decisions without fitting anything."""

import dataclasses
import types

import jax
import numpy as np
import pytest
from helpers import validation

import jaxhyst as jh
import jaxhyst._diagnose._diagnose as engine


FAMILY = jh.families.StructuralFamily()
MODEL = jh.StructuralBoucWen(10.0, 0.05, 1.0, 0.3, 0.2, 1.5)
TAGS = FAMILY.effect_names


def _finding(effect: str) -> jh.Finding:
    return jh.Finding(effect, "", "", 1.0, {}, {}, {}, validation())


def _output(effect: str) -> np.ndarray:
    """A stand-in model output that says which effect it came from."""
    return np.full(4, float(TAGS.index(effect)))


def _effect_of(output: np.ndarray) -> str:
    return TAGS[int(output[0])]


@pytest.fixture
def stage(monkeypatch):
    """(run, swaps): `run(adopted, heldout_mse, *, untried=(), se=1.0)` runs the stage
    with `adopted` as the one finding, every other effect of `heldout_mse` (but
    `untried`) a validated rival, and the stand-ins answering with these held-out
    MSEs; `swaps` records each replacement as (replaced, by, resolved)."""
    swaps: list[tuple[str, str, bool]] = []

    def refit(ctx, state, start, names, **_):
        added = [n for n in names if n not in state.free]
        (effect,) = {
            e.name for e in FAMILY.catalogue if set(added) <= set(e.parameters)
        }
        return types.SimpleNamespace(effect=effect)

    def predict(ctx, model):
        # The model without the finding (`_validated_in_place`'s baseline) is
        # MODEL itself: any finite output.
        return _output(model.effect) if hasattr(model, "effect") else np.zeros(4)

    def replace_finding(ctx, state, position, swap):
        swaps.append(
            (state.findings[position].effect, swap.alternative.name, swap.resolved)
        )
        findings = list(state.findings)
        findings[position] = _finding(swap.alternative.name)
        return dataclasses.replace(
            state,
            findings=tuple(findings),
            predicted=_output(swap.alternative.name),
            free=tuple(FAMILY.effect(swap.alternative.name).parameters),
        )

    def run(
        adopted,
        heldout_mse,
        *,
        untried=(),
        failed=(),
        se=1.0,
        comparison=None,
        policy=jh.families.AdoptionPolicy(),
    ):
        """... `failed`: effects that failed validation (neither validated nor
        untried)."""

        def by_effect(ctx, state, kept, other):
            return heldout_mse[_effect_of(kept)], heldout_mse[_effect_of(other)], se

        monkeypatch.setattr(engine, "_heldout_comparison", comparison or by_effect)
        trial = engine._Trial(
            jh.diagnosis.Score("x", 1.0, 1, -5.0, 0.0, True, {}, np.zeros((1, 1))),
            MODEL,
            np.zeros(4),
            validation(),
        )
        others = [n for n in heldout_mse if n != adopted]
        state = engine._State(
            current=MODEL,
            predicted=_output(adopted),
            free=FAMILY.effect(adopted).parameters,
            findings=(_finding(adopted),),
            passed_trials={
                n: (trial, {})
                for n in [adopted, *others]
                if n not in untried and n not in failed
            },
            untried={n: trial.score for n in untried},
            failed_trials={n: trial for n in failed},
            rounds=([dataclasses.replace(trial.score, effect=n) for n in heldout_mse],),
        )
        ctx = types.SimpleNamespace(
            family=FAMILY,
            policy=policy,
            hidden=frozenset(),
            fit_mask=np.ones(4, bool),
            progress=types.SimpleNamespace(say=lambda message: None),
            key=jax.random.key(0),
            sample_rate=1.0,
            duration=1.0,
            y=np.full(4, 100.0),
            hold_mask=np.ones(4, bool),
        )
        return engine._rivals(ctx, state)  # pyright: ignore[reportArgumentType]

    monkeypatch.setattr(engine, "_refit", refit)
    monkeypatch.setattr(engine, "_predict", predict)
    monkeypatch.setattr(engine, "_replace_finding", replace_finding)
    monkeypatch.setattr(
        engine,
        "_best_start",
        lambda ctx, effect, without, step, scales, **_: (MODEL, float("inf")),
    )
    return run, swaps


def test_a_rival_better_beyond_the_resolution_replaces_the_finding(stage):
    run, swaps = stage
    state = run("drift", {"drift": 20.0, "asymmetry": 10.0, "pinching": 30.0})
    assert swaps == [("drift", "asymmetry", True)]
    assert state.adopted == ("asymmetry",)
    assert state.findings[0].decided  # drift and pinching lost by 10 and 20


def test_among_rivals_the_record_cannot_tell_apart_the_lower_held_out_error_stays(
    stage,
):
    run, swaps = stage
    # asymmetry better by 1.5 standard errors, pinching worse by 1: both within.
    state = run("drift", {"drift": 17.0, "asymmetry": 14.0, "pinching": 19.0}, se=2.0)
    assert swaps == [("drift", "asymmetry", False)]
    assert state.adopted == ("asymmetry",)
    finding = state.findings[0]
    assert not finding.decided
    assert {r.effect for r in finding.rivals} == {"drift", "pinching"}
    (said,) = (a for a in state.ambiguities if "cannot tell asymmetry" in a.statement)
    assert "held-out error is the lowest" in said.statement
    assert set(said.undecided) == {"asymmetry", "drift", "pinching"}


def test_the_best_of_several_close_rivals_takes_the_place(stage):
    run, swaps = stage
    run("drift", {"drift": 17.0, "pinching": 16.0, "asymmetry": 15.0}, se=2.0)
    assert swaps == [("drift", "asymmetry", False)]


def test_a_close_rival_never_validated_alone_does_not_replace_the_finding(stage):
    run, swaps = stage
    state = run(
        "drift",
        {"drift": 17.0, "asymmetry": 14.0},
        untried=("asymmetry",),
        se=2.0,
    )
    assert swaps == []
    assert state.adopted == ("drift",)
    (said,) = (a for a in state.ambiguities if "cannot tell drift" in a.statement)
    assert "adopted first; the better rival was never validated alone" in (
        said.statement
    )


def test_an_effect_that_failed_validation_is_a_rival_too(stage, monkeypatch):
    """Pinching failed validation while drift stood in for it: it is still
    refitted in drift's place (polished from its failed refit's values, without a
    swarm of its own), and the record cannot tell the two apart. Without
    whole-catalogue rivals it is never compared."""
    run, swaps = stage
    refit, swarmed = engine._refit, []

    def recording_keys(ctx, state, start, names, **options):
        swarmed.append(options.get("key") is not None)
        return refit(ctx, state, start, names, **options)

    monkeypatch.setattr(engine, "_refit", recording_keys)
    mse = {"drift": 17.0, "pinching": 18.0, "asymmetry": 40.0}
    state = run("drift", mse, failed=("pinching", "asymmetry"), se=2.0)
    assert swaps == []
    assert swarmed == [False, False]
    finding = state.findings[0]
    assert {r.effect for r in finding.rivals} == {"pinching", "asymmetry"}
    assert not finding.decided
    (said,) = (a for a in state.ambiguities if "cannot tell drift" in a.statement)
    assert set(said.undecided) == {"drift", "pinching"}
    narrow = jh.families.AdoptionPolicy(whole_catalogue_rivals=False)
    state = run("drift", mse, failed=("pinching", "asymmetry"), se=2.0, policy=narrow)
    assert state.findings[0].rivals == ()
    assert state.findings[0].decided


def test_a_rival_that_failed_validation_never_replaces_the_finding(stage):
    """Refitted in drift's place, pinching fits the held-out data better beyond
    the resolution, but it did not pass validation on its own: drift stays,
    undecided, and the ambiguity names both."""
    run, swaps = stage
    state = run("drift", {"drift": 30.0, "pinching": 10.0}, failed=("pinching",))
    assert swaps == []
    assert state.adopted == ("drift",)
    assert not state.findings[0].decided
    (said,) = (a for a in state.ambiguities if "cannot tell drift" in a.statement)
    assert set(said.undecided) == {"drift", "pinching"}


def test_an_effect_replaced_within_the_resolution_does_not_come_back(stage):
    run, swaps = stage

    # Each effect, refitted in the other's place, looks better by one standard
    # error (refits that end at different points): one swap, no ping-pong.
    def rival_always_better(ctx, state, kept, other):
        return 10.0, 9.0, 1.0

    state = run(
        "drift", {"drift": 0.0, "asymmetry": 0.0}, comparison=rival_always_better
    )
    assert swaps == [("drift", "asymmetry", False)]
    (said,) = (a for a in state.ambiguities if "cannot tell asymmetry" in a.statement)
    assert "it replaced drift first" in said.statement


def test_a_replacement_supersedes_what_was_said_of_it_before(monkeypatch):
    """Once asymmetry takes drift's place, "cannot tell whether asymmetry is
    present" (asked with drift in the model) and the advice that would test it are
    dropped; statements about other effects stay."""
    monkeypatch.setattr(engine, "_refit", lambda ctx, state, model, names, **_: model)
    monkeypatch.setattr(engine, "_predict", lambda ctx, model: np.zeros(4))
    monkeypatch.setattr(engine, "_evidence", lambda *args: "")
    ctx = types.SimpleNamespace(
        family=types.SimpleNamespace(describe=lambda where: ""),
        progress=types.SimpleNamespace(say=lambda message: None),
        policy=jh.families.AdoptionPolicy(),
        y=np.ones(4),
        hold_mask=np.ones(4, bool),
        fit_mask=np.ones(4, bool),
    )
    said = tuple(
        engine.Ambiguity(f"cannot tell whether {name} is present", (name,))
        for name in ("asymmetry", "pinching")
    )
    state = engine._State(
        current=MODEL,
        predicted=np.ones(4),
        free=FAMILY.effect("drift").parameters,
        findings=(_finding("drift"),),
        ambiguities=said,
        contrasts=tuple(
            engine._Contrast((name,), MODEL, MODEL)
            for name in ("asymmetry", "pinching")
        ),
    )
    trial = engine._Trial(
        jh.diagnosis.Score("asymmetry", 1.0, 1, -5.0, 0.0, True, {}, np.zeros((1, 1))),
        MODEL,
        np.zeros(4),
        validation(),
    )
    swap = engine._Swap(
        trial,
        {},
        FAMILY.effect("asymmetry"),
        MODEL,
        np.zeros(4),
        FAMILY.effect("asymmetry").parameters,
        1.0,
        0.5,
        resolved=False,
    )
    state = engine._replace_finding(ctx, state, 0, swap)  # pyright: ignore[reportArgumentType]
    assert state.adopted == ("asymmetry",)
    statements = [a.statement for a in state.ambiguities]
    assert "cannot tell whether pinching is present" in statements
    assert "cannot tell whether asymmetry is present" not in statements
    assert "within the resolution" in statements[-1]
    assert [c.separates for c in state.contrasts] == [("pinching",)]


def _swap_setup(trial_model):
    """A state with asymmetry adopted, and drift's trial from before it (fitted with
    the base parameters free and `trial_model`'s other values)."""
    adopted = FAMILY.effect("asymmetry")
    drift = FAMILY.effect("drift")
    current = MODEL.replace(yield_skew=0.1, stiffness_skew=0.05, k=11.0)
    trial = engine._Trial(
        jh.diagnosis.Score("drift", 1.0, 1, -5.0, 0.0, True, {}, np.zeros((1, 1))),
        trial_model,
        np.full(4, 7.0),
        validation(),
        free=(*FAMILY.base_free, *drift.parameters),
    )
    state = engine._State(
        current=current,
        predicted=np.zeros(4),
        free=(*FAMILY.base_free, *adopted.parameters),
        findings=(_finding("asymmetry"),),
        passed_trials={"drift": (trial, {})},
    )
    ctx = types.SimpleNamespace(family=FAMILY, key=jax.random.key(0))
    return ctx, state, adopted, trial


def test_a_rival_whose_trial_fitted_the_same_model_is_not_refitted(monkeypatch):
    refits = []

    def refit(ctx, state, start, names, **_):
        refits.append(names)
        return start

    monkeypatch.setattr(engine, "_refit", refit)
    monkeypatch.setattr(engine, "_predict", lambda ctx, model: np.zeros(4))
    # Drift was tried with the base parameters free and asymmetry off, which is
    # what swapping it in for asymmetry fits: its trial is the swap.
    fitted = MODEL.replace(k=9.0, offset=0.3, trend=0.01)
    ctx, state, adopted, trial = _swap_setup(fitted)
    names, swapped, predicted = engine._swapped_in(ctx, state, 0, adopted, "drift")  # pyright: ignore[reportArgumentType]
    assert refits == []
    assert swapped is trial.model
    np.testing.assert_array_equal(predicted, trial.predicted)
    assert set(names) == set(trial.free)
    # A shape parameter of an effect that is off in both (a pinching width set
    # since the trial, pinching switched off) moves nothing: the same model.
    ctx, state, adopted, trial = _swap_setup(fitted)
    state = dataclasses.replace(state, current=state.current.replace(pinch_width=0.7))
    _, swapped, _ = engine._swapped_in(ctx, state, 0, adopted, "drift")  # pyright: ignore[reportArgumentType]
    assert refits == []
    assert swapped is trial.model
    # A value the refit holds fixed differs (the same width, with pinching on in
    # both): another model, refitted.
    ctx, state, adopted, trial = _swap_setup(fitted.replace(pinch=0.2))
    state = dataclasses.replace(
        state, current=state.current.replace(pinch=0.2, pinch_width=0.7)
    )
    engine._swapped_in(ctx, state, 0, adopted, "drift")  # pyright: ignore[reportArgumentType]
    assert len(refits) == 1
    # So do other free parameters (the trial's dependents, or another base).
    ctx, state, adopted, trial = _swap_setup(fitted)
    trial = dataclasses.replace(trial, free=(*trial.free, "pinch"))
    state = dataclasses.replace(state, passed_trials={"drift": (trial, {})})
    engine._swapped_in(ctx, state, 0, adopted, "drift")  # pyright: ignore[reportArgumentType]
    assert len(refits) == 2


def test_a_rival_whose_refit_hits_a_bug_is_skipped_with_its_traceback(
    stage, monkeypatch
):
    """A jaxhyst error in one rival's refit is warned with its traceback; the other
    rivals are still compared and the finding stays."""
    run, swaps = stage
    refit = engine._refit

    def broken_for_pinching(ctx, state, start, names, **options):
        if "pinch" in names:
            raise ValueError("a bound with no interval")
        return refit(ctx, state, start, names, **options)

    monkeypatch.setattr(engine, "_refit", broken_for_pinching)
    with pytest.warns(RuntimeWarning, match="refitting pinching failed") as said:
        state = run("drift", {"drift": 10.0, "pinching": 1.0, "asymmetry": 30.0})
    assert "a bound with no interval" in str(said[0].message)
    assert "Traceback" in str(said[0].message)
    assert swaps == []
    assert [r.effect for r in state.findings[0].rivals] == ["asymmetry"]


def test_a_candidate_whose_refit_hits_a_bug_is_rejected_not_fatal(monkeypatch):
    def broken(*args, **kwargs):
        raise ValueError("a bound with no interval")

    monkeypatch.setattr(engine, "_refit", broken)
    ctx = types.SimpleNamespace(policy=jh.families.AdoptionPolicy())
    state = engine._State(current=MODEL, predicted=np.zeros(4), free=())
    score = jh.diagnosis.Score("drift", 1.0, 1, -5.0, 0.0, True, {}, np.zeros((1, 1)))
    effect = FAMILY.effect("drift")
    with pytest.warns(RuntimeWarning, match="Traceback"):
        trial = engine._trial(ctx, state, score, (effect,), MODEL, jax.random.key(0))  # pyright: ignore[reportArgumentType]
    assert isinstance(trial, engine._Failed)
    assert "error in jaxhyst (ValueError: a bound with no interval)" in trial.reason
