"""Recordings at different sample rates fitted, diagnosed and evaluated together:
each simulated on its own time grid (a per-record step in the vmapped simulation),
none resampled."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxhyst as jh
from jaxhyst.identification import Problem, stack_problems


TRUTH = jh.PiezoBoucWen(2.0e-6, 0.6, 1.0 / 80.0, 0.02, -0.006, 1.2)
TEMPLATE = jh.PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5)
# A stage with dynamics: its output depends on the time step, not only the path.
STAGE = jh.PiezoStage(
    k1=0.3, k2=1.0, A1=0.5, beta1=0.6, gamma1=0.2, n=1.5,
    natural_frequency=12.0, damping_ratio=0.3,
)  # fmt: skip


def _sine_record(frequency, amplitude, periods, rate, *, seed, name, noise=1e-3):
    t = np.arange(int(periods * rate / frequency) + 1) / rate
    u = amplitude * 0.5 * (1 - np.cos(2 * np.pi * frequency * t))
    y = np.asarray(jh.simulate(TRUTH, jh.InputPath(0.0, 1 / rate, u)))
    sigma = noise * np.max(np.abs(y))
    y = y + sigma * np.random.default_rng(seed).standard_normal(y.size)
    return jh.Recording(t, u, y, name=name), sigma


def _problem(recording, model, solver=jh.RK4()):
    space = jh.ParameterSpace.default(model, recording)
    return Problem(space, recording.input_path(), jnp.asarray(recording.y), solver)


def test_stacked_simulation_at_two_rates_equals_each_alone():
    # 0.25 Hz at 200 samples/s beside 1 Hz at 1 kHz: each record steps its own dt.
    slow, _ = _sine_record(0.25, 1.0, 1, 200.0, seed=0, name="slow")
    fast, _ = _sine_record(1.0, 0.7, 1, 1000.0, seed=1, name="fast")
    assert slow.num_samples < fast.num_samples  # the slow record is padded
    for solver in (jh.RK4(), jh.RK4(substeps=2), jh.RK4(samples_per_step=4)):
        stacked = stack_problems([_problem(r, STAGE, solver) for r in (slow, fast)])
        np.testing.assert_array_equal(np.asarray(stacked.inputs.dt), [slow.dt, fast.dt])
        together = np.asarray(stacked.simulated(STAGE))
        for row, record in zip(together, (slow, fast)):
            alone = np.asarray(
                jh.simulate(STAGE, record.input_path(), solver, throw=False)
            )
            np.testing.assert_array_equal(row[: record.num_samples], alone)
    # The step matters: the slow record simulated at the fast record's step differs.
    wrong = jh.InputPath(0.0, fast.dt, slow.u)
    assert not np.allclose(
        np.asarray(jh.simulate(STAGE, wrong)), together[0, : slow.num_samples]
    )


def test_joint_fit_at_two_rates_recovers_the_truth_as_at_one_rate():
    slow, sigma_slow = _sine_record(0.25, 80.0, 1, 200.0, seed=0, name="slow")
    fast, sigma_fast = _sine_record(1.0, 50.0, 1, 1000.0, seed=1, name="fast")
    swarm = jh.MPSO(num_particles=48, num_iterations=120)
    mixed = jh.identify(TEMPLATE, [slow, fast], key=jax.random.key(0), swarm=swarm)
    assert jh.status_name(mixed.result) == "successful"
    assert [m.recording for m in mixed.per_recording] == ["slow", "fast"]
    assert [p.shape for p in mixed.predicted] == [
        (slow.num_samples,),
        (fast.num_samples,),
    ]
    for m, sigma in zip(mixed.per_recording, (sigma_slow, sigma_fast)):
        assert m.metrics["rmse"] < 1.2 * sigma
    # The same two tests at one rate (the fast one at 200 samples/s too).
    fast_200, _ = _sine_record(1.0, 50.0, 1, 200.0, seed=1, name="fast")
    one = jh.identify(TEMPLATE, [slow, fast_200], key=jax.random.key(0), swarm=swarm)
    # Against the truth: the gauge-free n, and the noise-free output on a test
    # neither fit saw (A1 is fixed by the gauge, so k2, beta1, gamma1 are the
    # truth's rescaled; k1 = 2e-6 barely shows in the output).
    check, _ = _sine_record(0.5, 65.0, 1, 500.0, seed=2, name="check", noise=0)
    path = check.input_path()

    def errors(fit):
        out = np.asarray(jh.simulate(fit.model, path))
        return (
            abs(float(fit.model.n / TRUTH.n) - 1),
            jh.metrics.rmse(check.y, out) / float(np.max(np.abs(check.y))),
        )

    for e_mixed, e_one in zip(errors(mixed), errors(one)):
        assert e_mixed < max(1e-3, 2 * e_one)


def test_command_line_fits_and_evaluates_two_rates(tmp_path, capsys):
    from jaxhyst._cli._main import main

    slow, _ = _sine_record(0.25, 80.0, 1, 200.0, seed=0, name="slow")
    fast, _ = _sine_record(1.0, 50.0, 1, 1000.0, seed=1, name="fast")
    paths = []
    for recording in (slow, fast):
        path = tmp_path / f"{recording.name}.csv"
        recording.save(path)
        paths.append(str(path))
    out = tmp_path / "fit.json"
    argv = ["fit", *paths, "--json", str(out), "--particles", "16"]
    assert main([*argv, "--iterations", "20"]) == 0
    stdout = capsys.readouterr().out
    assert "200 Hz" in stdout and "1000 Hz" in stdout
    data = json.loads(out.read_text())
    assert [r["sample_rate_hz"] for r in data["recordings"]] == [200.0, 1000.0]
    assert [m["recording"] for m in data["metrics"]["per_recording"]] == [
        "slow",
        "fast",
    ]
    # The model file evaluates on both files, each at its own rate.
    scores = tmp_path / "scores.json"
    assert main(["evaluate", str(out), *paths, "--json", str(scores)]) == 0
    rows = json.loads(scores.read_text())["recordings"]
    assert [row["samples"] for row in rows] == [slow.num_samples, fast.num_samples]
    for row, fitted in zip(rows, data["metrics"]["per_recording"]):
        assert row["metrics"]["rmse"] == pytest.approx(fitted["rmse"], rel=1e-6)


def _piezo_record(truth, freqs, amps, rate, duration, name, rng, sigma=0.002):
    # Multisines start at zero, so each test starts from rest like the model.
    t = np.arange(int(duration * rate) + 1) / rate
    u = sum(a * np.sin(2 * np.pi * f * t) for f, a in zip(freqs, amps))
    y = np.asarray(jh.simulate(truth, jh.InputPath.from_samples(t, u)))
    return jh.Recording(t, u, y + sigma * rng.standard_normal(t.size), name=name)


@pytest.mark.slow  # 88-104 s; the quick tests below check its plumbing
def test_two_rates_are_diagnosed_as_one_specimen():
    # A slow test at 200 samples/s beside a fast one at 1 kHz of one piezo stage
    # whose asymmetry (eps*u*sign(udot)) the base model does not have.
    sigma = 0.002
    truth = jh.CorrectedPiezoBoucWen(
        k1=0.3, k2=1.0, A1=0.5, beta1=0.6, gamma1=0.2, n=1.5, eps=0.2
    )
    rng = np.random.default_rng(0)
    slow = _piezo_record(truth, (0.5, 1.7), (1.0, 0.5), 200.0, 4.0, "slow", rng)
    fast = _piezo_record(truth, (2.0, 5.3), (0.7, 0.3), 1000.0, 1.0, "fast", rng)
    base = jh.PiezoBoucWen(k1=0.3, k2=1.0, A1=0.5, beta1=0.6, gamma1=0.2, n=1.5)
    diagnosis = jh.diagnose([slow, fast], key=jax.random.key(0), base=base)
    assert diagnosis.effects == ("asymmetry",)
    assert diagnosis.samples == slow.num_samples + fast.num_samples
    # Held-out data in each recording.
    split = np.split(diagnosis.heldout, [slow.num_samples])
    assert all(0.1 < part.mean() < 0.5 for part in split)
    per = diagnosis.to_dict()["per_recording"]
    assert [p["samples"] for p in per] == [slow.num_samples, fast.num_samples]
    for p in per:
        assert p["final"]["rmse"] < 1.3 * sigma < p["baseline"]["rmse"]
    # Each recording simulated alone at its own rate gives the joined prediction.
    alone = np.concatenate(
        [
            np.asarray(jh.simulate(diagnosis.final_model, r.input_path()))
            for r in (slow, fast)
        ]
    )
    np.testing.assert_allclose(diagnosis.final_predicted, alone, rtol=0, atol=1e-9)


def test_recordings_at_two_rates_join_and_simulate_as_a_diagnosis_reads_them():
    from jaxhyst._diagnose._records import DiagnosisRecords

    slow, _ = _sine_record(0.25, 1.0, 1, 200.0, seed=0, name="slow")
    fast, _ = _sine_record(1.0, 0.7, 1, 1000.0, seed=1, name="fast")
    with pytest.raises(jh.RecordingError, match="mixed_rates=True"):
        jh.Recording.join([slow, fast])
    joined = jh.Recording.join([slow, fast], mixed_rates=True)
    # Every sample kept, in order, on a time axis at the finest step.
    assert joined.num_samples == slow.num_samples + fast.num_samples
    np.testing.assert_array_equal(joined.y, np.concatenate([slow.y, fast.y]))
    assert joined.dt == pytest.approx(fast.dt)
    # One rate: the join is as before (the first recording's step).
    same = jh.Recording.join([fast, fast], mixed_rates=True)
    np.testing.assert_array_equal(same.t, jh.Recording.join([fast, fast]).t)

    records = DiagnosisRecords.of((slow, fast), "test")
    assert records.mixed_rates and records.joined.name == "slow + fast"
    np.testing.assert_array_equal(np.asarray(records.inputs.dt), [slow.dt, fast.dt])
    assert records.step == pytest.approx(fast.dt)
    assert records.duration == pytest.approx(slow.duration + fast.duration)
    # The refit stride: the smallest any recording asks for.
    family = jh.families.PiezoFamily()
    model = family.extend(TRUTH, joined)
    assert records.stride(family, model) == min(
        family.refit_stride(model, r) for r in (slow, fast)
    )
    assert family.refit_stride(model, fast) > records.stride(family, model)
    # Each recording simulated at its own step, as alone.
    solver = jh.RK4()
    alone = [
        np.asarray(jh.simulate(STAGE, r.input_path(), solver)) for r in (slow, fast)
    ]
    np.testing.assert_array_equal(records.predict(STAGE, solver), np.concatenate(alone))
    # A batch of models (vmapped twice) agrees to rounding.
    np.testing.assert_allclose(
        records.predict_each([STAGE, STAGE], solver)[1],
        np.concatenate(alone),
        rtol=1e-13,
        atol=1e-16,
    )


@pytest.mark.slow  # 62 s, 330 s under load (the whole diagnosis at two rates)
def test_command_line_diagnoses_two_rates(tmp_path, capsys):
    from jaxhyst._cli._main import main

    truth = jh.CorrectedPiezoBoucWen(
        k1=0.3, k2=1.0, A1=0.5, beta1=0.6, gamma1=0.2, n=1.5, eps=0.2
    )
    rng = np.random.default_rng(0)
    slow = _piezo_record(truth, (0.5, 1.7), (1.0, 0.5), 200.0, 4.0, "slow", rng)
    fast = _piezo_record(truth, (2.0, 5.3), (0.7, 0.3), 1000.0, 1.0, "fast", rng)
    paths = []
    for recording in (slow, fast):
        path = tmp_path / f"{recording.name}.csv"
        recording.save(path)
        paths.append(str(path))
    out = tmp_path / "diagnosis.json"
    report = tmp_path / "report.md"
    argv = ["diagnose", *paths, "--json", str(out), "--report", str(report)]
    assert main([*argv, "--particles", "16", "--iterations", "20"]) == 0
    stdout = capsys.readouterr().out
    assert "slow, 801 samples at 200 Hz" in stdout
    assert "fast, 1001 samples at 1000 Hz" in stdout
    data = json.loads(out.read_text())
    assert data["final"]["model"] == "piezo+asymmetry"
    assert [p["samples"] for p in data["per_recording"]] == [801, 1001]
    rates = [r["sample_rate_hz"] for r in data["model_file"]["recordings"]]
    assert rates == [200.0, 1000.0]
    assert report.exists()
