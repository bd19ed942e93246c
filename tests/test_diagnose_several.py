"""`diagnose` over several recordings of one specimen: one model for all of them,
each recording simulated from its own initial state, held-out data in each."""

import json

import jax
import numpy as np
import pytest

import jaxhyst as jh


RATE = 100.0
SIGMA = 0.002


def _record(truth, freqs, amps, name, rng, duration=6.0):
    # Multisines start at zero, so each test starts from rest like the model.
    t = np.arange(int(duration * RATE) + 1) / RATE
    u = sum(a * np.sin(2 * np.pi * f * t) for f, a in zip(freqs, amps))
    y = np.asarray(jh.simulate(truth, jh.InputPath.from_samples(t, u)))
    return jh.Recording(t, u, y + SIGMA * rng.standard_normal(t.size), name=name)


def _specimen(eps):
    # The paper's asymmetry term (eps*u*sign(udot)), not the catalogue's form.
    truth = jh.CorrectedPiezoBoucWen(
        k1=0.3, k2=1.0, A1=0.5, beta1=0.6, gamma1=0.2, n=1.5, eps=eps
    )
    rng = np.random.default_rng(0)
    return [
        _record(truth, (0.5, 1.7, 4.1), (1.0, 0.5, 0.25), "slow", rng),
        _record(truth, (0.8, 2.3, 5.3), (0.7, 0.4, 0.2), "fast", rng),
    ]


@pytest.mark.slow  # 99 s under load; the several-recordings path keeps the fast command-line test
def test_two_recordings_are_diagnosed_as_one_specimen():
    slow, fast = _specimen(eps=0.2)
    diagnosis = jh.diagnose([slow, fast], key=jax.random.key(0))
    assert diagnosis.effects == ("asymmetry",)
    assert diagnosis.samples == slow.num_samples + fast.num_samples
    # Held-out data in each recording.
    split = np.split(diagnosis.heldout, [slow.num_samples])
    assert all(0.1 < part.mean() < 0.5 for part in split)
    report = diagnosis.to_dict()
    per = report["per_recording"]
    assert [p["recording"] for p in per] == ["slow", "fast"]
    assert [p["samples"] for p in per] == [slow.num_samples, fast.num_samples]
    for p in per:
        assert p["final"]["rmse"] < 1.3 * SIGMA < p["baseline"]["rmse"]
    # Each recording restarts from rest: the joined prediction equals simulating
    # the final model on each recording alone.
    alone = np.concatenate(
        [
            np.asarray(jh.simulate(diagnosis.final_model, r.input_path()))
            for r in (slow, fast)
        ]
    )
    np.testing.assert_allclose(diagnosis.final_predicted, alone, rtol=0, atol=1e-9)


def test_one_recording_has_no_per_recording_key():
    slow, _ = _specimen(eps=0.0)
    base = jh.PiezoBoucWen(k1=0.3, k2=1.0, A1=0.5, beta1=0.6, gamma1=0.2, n=1.5)
    diagnosis = jh.diagnose(slow, key=jax.random.key(0), base=base)
    assert diagnosis.per_recording == ()
    assert "per_recording" not in diagnosis.to_dict()


def test_several_recordings_bad_input():
    slow, fast = _specimen(eps=0.0)
    with pytest.raises(ValueError, match="empty"):
        jh.diagnose([], key=jax.random.key(0))
    with pytest.raises(TypeError, match=r"recording\[1\] must be a Recording"):
        jh.diagnose([slow, "fast.csv"], key=jax.random.key(0))  # pyright: ignore[reportArgumentType]
    other_units = jh.Recording(
        fast.t, fast.u, fast.y, name="fast", input_unit="V", output_unit="mm"
    )
    with pytest.raises(ValueError, match="units"):
        jh.diagnose([slow, other_units], key=jax.random.key(0))


def test_command_line_diagnoses_several_files(tmp_path, capsys):
    from jaxhyst._cli import main

    paths = []
    for recording in _specimen(eps=0.2):
        path = tmp_path / f"{recording.name}.csv"
        recording.save(path)
        paths.append(str(path))
    out = tmp_path / "diagnosis.json"
    assert main(["diagnose", *paths, "--json", str(out), "--seed", "0"]) == 0
    data = json.loads(out.read_text())
    assert data["recording"] == "slow + fast"
    assert [p["recording"] for p in data["per_recording"]] == ["slow", "fast"]
    assert data["final"]["model"] == "piezo+asymmetry"
    # The model file names both recordings it came from, and loads.
    assert [r["name"] for r in data["model_file"]["recordings"]] == ["slow", "fast"]
    loaded = jh.load_model(out)
    assert loaded.effects == ("asymmetry",) and len(loaded.recordings) == 2
    assert "asymmetry" in capsys.readouterr().out
