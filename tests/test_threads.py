"""Independent host work side by side (`_threads.side_by_side`), and the diagnosis
stages that use it giving what they gave one at a time."""

import threading
import time
import types

import jax
import numpy as np
import pytest

from jaxhyst import _threads
from jaxhyst._diagnose import _diagnose
from jaxhyst._diagnose._results import Score
from jaxhyst._threads import side_by_side


@pytest.fixture
def two_cores(monkeypatch):
    monkeypatch.setattr(_threads, "host_cores", lambda: 2)


def test_results_come_in_order_from_worker_threads(two_cores):
    def slow_square(x):
        time.sleep(0.05 * (3 - x))  # the first finishes last
        return x * x, threading.current_thread().name

    with side_by_side(slow_square, [0, 1, 2]) as results:
        out = list(results)
    assert [value for value, _ in out] == [0, 1, 4]
    assert all(name.startswith("jaxhyst-work") for _, name in out)


def test_two_items_run_at_the_same_time(two_cores):
    both = threading.Barrier(2, timeout=10)

    def meet(x):
        both.wait()  # deadlocks (BrokenBarrierError) unless both run at once
        return x

    with side_by_side(meet, ["a", "b"]) as results:
        assert list(results) == ["a", "b"]


def test_an_error_is_raised_where_its_result_is_read(two_cores):
    def check(x):
        if x == 1:
            raise KeyError("item 1 is broken")
        return x

    with side_by_side(check, [0, 1, 2]) as results:
        assert next(results) == 0
        with pytest.raises(KeyError, match="item 1 is broken"):
            next(results)


def test_stopping_early_drops_the_items_not_started(two_cores):
    started = []
    lock = threading.Lock()

    def record(x):
        with lock:
            started.append(x)
        time.sleep(0.05)
        return x

    items = list(range(20))
    with side_by_side(record, items) as results:
        for x in results:
            if x == 1:
                break
    assert len(started) < len(items)


def test_inside_a_worker_and_on_one_core_it_runs_in_the_calling_thread(
    two_cores, monkeypatch
):
    def inner(x):
        return threading.current_thread().name

    def outer(x):
        with side_by_side(inner, [x, x]) as results:
            return list(results)

    with side_by_side(outer, [0, 1]) as results:
        for here, names in zip(["jaxhyst-work"] * 2, results):
            assert all(n.startswith(here) for n in names)
            assert len(set(names)) == 1  # both inner items in the worker itself
    monkeypatch.setattr(_threads, "host_cores", lambda: 1)
    with side_by_side(inner, [0, 1]) as results:
        assert list(results) == [threading.current_thread().name] * 2


def _score(effect):
    return Score(effect, 10.0, 1, -5.0, 1.0, True, {}, np.zeros((1, 1)))


def test_candidate_keys_are_those_of_one_at_a_time_when_a_refit_diverges(
    two_cores, monkeypatch
):
    """A candidate's key counts the trials made before it: when an earlier one
    fails (diverges: no trial), a later one is tried again with the key it would
    have had one at a time."""
    keys = {}
    lock = threading.Lock()

    class Validation:
        accepted = True

    class Trial:
        def __init__(self, score):
            self.score = score
            self.validation = Validation()

    def trial(ctx, state, score, effects, start, key):
        with lock:
            keys.setdefault(score.effect, []).append(
                tuple(np.asarray(jax.random.key_data(key)))
            )
        if score.effect == "first":
            return _diagnose._Failed("the refitted model diverged")
        return Trial(score)

    scores = [_score("first"), _score("second"), _score("third")]
    monkeypatch.setattr(_diagnose, "refit_choice", lambda *a: (scores, False))
    monkeypatch.setattr(_diagnose, "_best_start", lambda *a, **k: (None, 1.0))
    monkeypatch.setattr(_diagnose, "_trial", trial)
    family = types.SimpleNamespace(effect=lambda name: name)
    ctx = types.SimpleNamespace(
        family=family,
        policy=None,
        progress=types.SimpleNamespace(say=lambda message: None),
        sample_rate=1.0,
        duration=1.0,
        key=jax.random.key(3),
    )
    state = types.SimpleNamespace(
        passed=frozenset(), natural={}, current=None, findings=()
    )
    _, trials = _diagnose._refit_candidates(ctx, state, scores)  # pyright: ignore[reportArgumentType]
    assert [t.score.effect for t in trials] == ["second", "third"]

    def key_of(number):
        return tuple(
            np.asarray(jax.random.key_data(jax.random.fold_in(ctx.key, number)))
        )

    # One at a time: "second" gets key 0 (no trial before it), "third" key 1.
    assert keys["second"][-1] == key_of(0)
    assert keys["third"][-1] == key_of(1)
    assert keys["first"] == [key_of(0)]
