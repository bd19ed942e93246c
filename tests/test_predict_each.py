"""`DiagnosisRecords.predict_each`: several models simulated in batches give what
each gives alone, in order, on one recording and on several."""

import jax
import numpy as np
import pytest

import jaxhyst as jh
from jaxhyst._diagnose._records import BATCH, DiagnosisRecords


RATE = 200.0


def _recording(seconds, name):
    t = np.arange(int(seconds * RATE) + 1) / RATE
    u = 1.5 * np.sin(2 * np.pi * 0.5 * t) + 0.4 * np.sin(2 * np.pi * 1.7 * t)
    return jh.Recording(t, u, np.zeros_like(u), name=name)


def _models(path):
    base = jh.PiezoBoucWen.paper_table4(3)
    off = jh.ExtendedPiezo.around(base, path)
    # More than one batch of one structure (each with its own values), and a lone
    # model of another structure in between.
    shifted = [off.replace(phi=0.002 * (i + 1)) for i in range(BATCH + 2)]
    dynamic = jh.ExtendedPiezo.around(base, path, dynamic=True)
    held = off.replace(eps=0.05).held_at_zero(["creep_slow", "offset"])
    return [*shifted[:3], dynamic, *shifted[3:], held]


@pytest.mark.parametrize("lengths", [(6.0,), (6.0, 4.0)])
def test_batched_predictions_equal_one_at_a_time(lengths):
    recordings = tuple(_recording(s, f"r{i}") for i, s in enumerate(lengths))
    records = DiagnosisRecords.of(recordings, "test")
    models = _models(records.one_input)
    solver = jh.RK4()
    batched = records.predict_each(models, solver)
    assert len(batched) == len(models)
    for model, predicted in zip(models, batched):
        alone = records.predict(model, solver)
        assert (
            predicted.shape == alone.shape == (sum(r.num_samples for r in recordings),)
        )
        # Equal up to how the compiler vectorises the batch.
        np.testing.assert_allclose(predicted, alone, rtol=1e-12, atol=1e-12)
    # The batch kept each model's own values (not a neighbour's or the padding's).
    assert not np.allclose(batched[0], batched[1])
    assert jax.tree.structure(models[3]) != jax.tree.structure(models[0])
