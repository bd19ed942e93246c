"""The pair refit (`_jointly`): when no candidate passes alone, the one that lowered
the held-out error most is refitted together with each other candidate in turn.

The refits themselves are replaced by a stand-in that records what it was asked
for, so these tests pin the stage's choices (which candidate leads, in which order
partners are tried, what stops it) without fitting anything."""

import types

import jax
import numpy as np
import pytest
from helpers import validation

import jaxhyst as jh
import jaxhyst._diagnose._diagnose as engine


def _trial(effect: str, after: float, *, dependents=()):
    score = jh.diagnosis.Score(
        effect, 1.0, 1, -1.0, 0.0, True, {f"{effect}_gain": 1.0}, np.zeros((1, 1))
    )
    return engine._Trial(
        score,
        jh.BoucWen(1.0, 0.1, 1.0, 1.0, 0.5, 0.5, 2.0),
        np.zeros(1),
        validation(1.0, after, accepted=False),
        dependents=dependents,
    )


@pytest.fixture
def pair_refits(monkeypatch):
    """(ctx, state, calls, passing): `_jointly`'s context, with `_refit_with`
    recording (leading effect, partner, partner's step) and passing the pairs whose
    partner is in `passing`."""
    calls: list[tuple[str, str, dict]] = []
    passing: set[str] = set()

    def refit_with(ctx, state, alone, effects, step, scales, key):
        lead, partner = (e.name for e in effects)
        calls.append((lead, partner, step))
        pair = _trial(lead, 0.5)
        checked = validation(1.0, 0.5, accepted=partner in passing)
        return engine._Trial(
            pair.score, pair.model, pair.predicted, checked, dependents=(partner,)
        )

    monkeypatch.setattr(engine, "_refit_with", refit_with)
    ctx = types.SimpleNamespace(
        family=jh.families.StructuralFamily(),
        sample_rate=1.0,
        duration=1.0,
        progress=types.SimpleNamespace(say=lambda message: None),
        key=jax.random.key(0),
    )
    state = types.SimpleNamespace(natural={}, findings=())
    return ctx, state, calls, passing


def test_the_best_candidate_leads_and_partners_follow_their_held_out_error(
    pair_refits,
):
    ctx, state, calls, passing = pair_refits
    passing.add("asymmetry")
    trials = [
        _trial("drift", 0.9),
        _trial("asymmetry", 0.95),
        _trial("pinching", 0.8),
        # Refitted with what it needs: not an independent candidate.
        _trial("degradation", 0.7, dependents=("drift",)),
    ]
    pair = engine._jointly(ctx, state, trials)  # pyright: ignore[reportArgumentType]
    assert [(lead, partner) for lead, partner, _ in calls] == [
        ("pinching", "drift"),
        ("pinching", "asymmetry"),
    ]
    # Each partner starts from its own score-test step.
    assert [step for *_, step in calls] == [
        {"drift_gain": 1.0},
        {"asymmetry_gain": 1.0},
    ]
    assert pair is not None and pair.joint and pair.validation.accepted
    assert pair.dependents == ("asymmetry",)


def test_no_pair_when_none_passes(pair_refits):
    ctx, state, calls, _ = pair_refits
    trials = [_trial("drift", 0.9), _trial("pinching", 0.8), _trial("asymmetry", 0.95)]
    assert engine._jointly(ctx, state, trials) is None  # pyright: ignore[reportArgumentType]
    assert len(calls) == 2


@pytest.mark.parametrize(
    "trials",
    [
        # The best candidate did not lower the held-out error at all.
        [_trial("drift", 1.0), _trial("pinching", 1.2)],
        # Only one independent candidate.
        [_trial("drift", 0.9), _trial("pinching", 0.8, dependents=("drift",))],
        [],
    ],
    ids=["no-gain", "one-candidate", "none"],
)
def test_no_pair_is_tried_without_two_candidates_and_a_gain(pair_refits, trials):
    ctx, state, calls, passing = pair_refits
    passing.update({"drift", "pinching"})
    assert engine._jointly(ctx, state, trials) is None  # pyright: ignore[reportArgumentType]
    assert calls == []
