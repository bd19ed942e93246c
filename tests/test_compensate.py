"""Hysteresis compensation by per-sample inversion."""

import jax
import numpy as np
import pytest

import jaxhyst as jh


PAPER = jh.PiezoBoucWen.paper_table4(3)


def _path(rate=500.0):
    return jh.sample(jh.paper_u1(), rate)


@pytest.mark.parametrize(
    "model",
    [
        PAPER,
        jh.CorrectedPiezoBoucWen.from_piezo(PAPER, phi=0.0, eps=2e-7),
        jh.ExtendedPiezo.around(PAPER, jh.sample(jh.paper_u1(), 500.0)).replace(
            creep_slow=0.1 * PAPER.k1, eps=1e-7, skew=0.5
        ),
    ],
    ids=["piezo", "corrected", "extended"],
)
def test_inverse_recovers_the_drive_that_made_the_reference(model):
    path = _path()
    reference = np.asarray(jh.simulate(model, path))
    result = jh.compensate(model, np.asarray(path.times), reference, limits=(0.0, 5.0))
    # The reference came from u1 through the same model: its inverse is u1.
    np.testing.assert_allclose(result.drive, path.values, atol=1e-9)
    np.testing.assert_allclose(
        result.predicted, reference, rtol=0, atol=1e-12 * np.ptp(reference)
    )
    # `predicted` is what the model does under the drive.
    again = jh.simulate(model, jh.InputPath(path.t0, path.dt, result.drive))
    np.testing.assert_allclose(again, result.predicted, rtol=0, atol=1e-15)
    assert not np.any(np.asarray(result.at_limit))
    assert result.tracking()["rms_error_percent_of_stroke"] < 1e-6
    assert jh.status_name(result.result) == "successful"


def test_out_of_reach_references_are_flagged_not_hidden():
    path = _path()
    plain = np.asarray(jh.simulate(PAPER, path))  # u1 spans the whole 0-4 V range
    reference = 1.3 * plain
    result = jh.compensate(PAPER, np.asarray(path.times), reference, limits=(0.0, 4.0))
    drive = np.asarray(result.drive)
    at_limit = np.asarray(result.at_limit)
    assert at_limit.any() and not at_limit.all()
    # Flagged samples sit at the upper limit, where the reference climbs above
    # the stroke 0-4 V gives, and the predicted output falls short of it.
    assert np.all(drive[at_limit] == 4.0)
    assert np.all(reference[at_limit] > 0.95 * plain.max())
    assert np.all(np.asarray(result.predicted)[at_limit] < reference[at_limit])
    # Elsewhere the reference is tracked.
    error = np.abs(np.asarray(result.error))
    assert np.max(error[~at_limit]) < 1e-9 * np.ptp(reference)
    assert result.tracking()["samples_at_limit"] == int(at_limit.sum())


def test_the_inverse_stays_on_the_branch_of_a_model_that_folds_far_from_the_drive():
    # A negative log-rate amplitude (as diagnoses fit on a record's rates) turns
    # A1 negative for one-sample jumps far beyond those rates: the one-sample
    # output folds over across the drive range. A bisection over the whole range
    # jumps between the folds (drive errors of the whole range, output blown up);
    # the nearest crossing from the present drive recovers the drive exactly.
    path = _path()
    model = jh.ExtendedPiezo.around(PAPER, path).replace(
        rate_amplitude=-0.33, rate_gain=0.23
    )
    lo, hi = 0.0, 5.0
    trial = jh.simulate(model, jh.InputPath(path.t0, path.dt, np.asarray([2.0, hi])))
    back = jh.simulate(model, jh.InputPath(path.t0, path.dt, np.asarray([2.0, 2.1])))
    assert float(trial[1]) < float(back[1])  # the fold: more drive, less output
    reference = np.asarray(jh.simulate(model, path))
    result = jh.compensate(model, np.asarray(path.times), reference, limits=(lo, hi))
    np.testing.assert_allclose(result.drive, path.values, atol=1e-9)
    assert not np.any(np.asarray(result.at_limit))
    assert result.tracking()["rms_error_percent_of_stroke"] < 1e-6
    # A reference below the model's reach at the lower limit: the drive waits at
    # the limit (flagged) instead of jumping up to a fold where the output falls.
    lower = reference - 0.05 * np.ptp(reference)
    result = jh.compensate(model, np.asarray(path.times), lower, limits=(lo, hi))
    drive, at_limit = np.asarray(result.drive), np.asarray(result.at_limit)
    assert at_limit.any() and np.all(drive[at_limit] == lo)
    largest_step = np.max(np.abs(np.diff(np.asarray(path.values))))
    assert np.max(np.abs(np.diff(drive))) < 3 * largest_step


@pytest.mark.parametrize(
    "model, method, words",
    [
        (
            jh.PiezoStage.from_piezo(PAPER, natural_frequency=100.0, damping_ratio=0.5),
            jh.PerSampleInversion(),
            "mass-spring.*DynamicInversion",
        ),
        (
            jh.CorrectedPiezoBoucWen.from_piezo(PAPER, phi=0.01, eps=0.0),
            jh.PerSampleInversion(),
            "phi = 0.01.*OptimisedDrive",
        ),
        (PAPER, jh.DynamicInversion(), "no stage dynamics.*PerSampleInversion"),
        (
            jh.ExtendedPiezo.around(PAPER, _path(100.0))
            .replace(phi=-0.02)
            .with_dynamics(20.0, 0.4),
            jh.DynamicInversion(),
            "phi = -0.02.*OptimisedDrive",
        ),
    ],
)
def test_a_method_refuses_models_it_cannot_invert(model, method, words):
    path = _path(100.0)
    with pytest.raises(ValueError, match=words):
        jh.compensate(
            model,
            np.asarray(path.times),
            np.zeros(path.num_samples),
            limits=(0.0, 5.0),
            method=method,
        )


_STAGE = jh.PiezoStage.from_piezo(PAPER, natural_frequency=15.0, damping_ratio=0.3)
_DRIFTING_STAGE = jh.ExtendedPiezo.around(
    PAPER, jh.InputPath(0.0, 1 / 500.0, np.zeros(1000))
).replace(trend=0.05 * PAPER.k1, curvature=0.02 * PAPER.k1)
_DRIFTING_STAGE = _DRIFTING_STAGE.with_dynamics(20.0, 0.4)


@pytest.mark.parametrize(
    "model, solver, method, expected",
    [
        (_STAGE, jh.RK4(substeps=4), None, "dynamic inversion"),
        (_DRIFTING_STAGE, jh.RK4(substeps=4), None, "dynamic inversion"),
        (_STAGE, jh.RK4(substeps=4), jh.OptimisedDrive(), "optimised drive"),
        (
            jh.CorrectedPiezoBoucWen.from_piezo(PAPER, phi=0.03, eps=0.0),
            jh.RK4(),
            None,
            "optimised drive",
        ),
    ],
    ids=["stage", "stage_with_drift", "stage_optimised", "time_shift"],
)
def test_lagging_models_get_a_drive_ahead_of_time(model, solver, method, expected):
    # A 2 Hz sine, fast enough that the lag matters: the quasi-static inverse
    # tracks poorly on the lagging model; the stage's dynamic inversion and the
    # optimised drive track it closely.
    t = np.arange(0.0, 2.0, 1 / 500.0)
    drive_made = 2 - 1.8 * np.cos(2 * np.pi * 2.0 * t)
    reference = np.asarray(
        jh.simulate(model, jh.InputPath(0.0, t[1], drive_made), solver)
    )
    result = jh.compensate(
        model, t, reference, limits=(0.0, 4.0), solver=solver, method=method
    )
    assert result.method == expected
    static = jh.compensate(
        jh.PiezoBoucWen(*(getattr(model, n) for n in jh.PiezoBoucWen.parameter_names)),
        t,
        reference,
        limits=(0.0, 4.0),
    )
    naive = np.asarray(
        jh.simulate(model, jh.InputPath(0.0, t[1], static.drive), solver)
    )
    naive_rms = np.sqrt(np.mean((naive - reference) ** 2))
    optimised_rms = np.sqrt(np.mean(np.asarray(result.error) ** 2))
    assert optimised_rms < 0.1 * naive_rms
    assert result.tracking()["rms_error_percent_of_stroke"] < 0.5
    again = jh.simulate(model, jh.InputPath(0.0, t[1], result.drive), solver)
    np.testing.assert_allclose(again, result.predicted, rtol=0, atol=1e-15)
    assert np.all((np.asarray(result.drive) > 0.0) & (np.asarray(result.drive) < 4.0))


@pytest.mark.parametrize("phi", [-0.02, 0.02])
def test_a_time_shifted_hysteresis_is_inverted_without_shifting_the_linear_term(phi):
    # y = k1*u(t) + k2*h[u(t + phi)]: only the hysteresis reads the shifted drive.
    # On ramps between holds, shifting the whole drive by phi mistimes k1*u (the
    # larger part of the output) by 20 ms. The fixed-point passes put the
    # hysteresis's share in time, so a few L-BFGS steps leave an exact drive.
    model = jh.CorrectedPiezoBoucWen.from_piezo(PAPER, phi=phi, eps=0.0)
    t = np.arange(0.0, 3.0, 1 / 200.0)
    levels = np.array([0.5, 3.5, 1.0, 3.0, 2.0])[np.minimum((t / 0.6).astype(int), 4)]
    ramp = np.ones(40) / 40  # 0.2 s ramps
    made = np.convolve(np.concatenate([np.full(40, levels[0]), levels]), ramp)
    made = made[40 : 40 + t.size]
    reference = np.asarray(jh.simulate(model, jh.InputPath(0.0, t[1], made)))
    method = jh.OptimisedDrive(steps=5)
    result = jh.compensate(model, t, reference, limits=(0.0, 4.0), method=method)
    assert result.tracking()["max_error_percent_of_stroke"] < 1e-3
    np.testing.assert_allclose(result.drive, made, atol=1e-4)


def test_drives_faster_than_the_slew_limit_are_flagged_not_smoothed():
    path = _path(500.0)
    t = np.asarray(path.times)
    reference = np.asarray(jh.simulate(PAPER, path))
    free = jh.compensate(PAPER, t, reference, limits=(0.0, 5.0))
    assert free.over_slew is None and free.tracking()["samples_over_slew"] == 0
    rate = np.abs(np.diff(np.asarray(free.drive))) * 500.0
    np.testing.assert_allclose(free.tracking()["max_slew_rate"], rate.max())
    limit = 0.5 * rate.max()  # u1 = 2 - 2 cos(0.2 pi t) peaks at 0.4 pi V/s
    result = jh.compensate(PAPER, t, reference, limits=(0.0, 5.0), slew_limit=limit)
    flagged = np.asarray(result.over_slew)
    assert flagged.shape == t.shape and not flagged[0]
    np.testing.assert_array_equal(flagged[1:], rate > limit)
    assert 0 < result.tracking()["samples_over_slew"] == int(flagged.sum())
    # The drive is the same: the limit is reported, never smoothed away.
    np.testing.assert_array_equal(result.drive, free.drive)
    with pytest.raises(ValueError, match="slew_limit must be positive"):
        jh.compensate(PAPER, t, reference, limits=(0.0, 5.0), slew_limit=-1.0)
    with pytest.raises(TypeError, match="slew_limit must be a number"):
        jh.compensate(PAPER, t, reference, limits=(0.0, 5.0), slew_limit="fast")  # type: ignore[arg-type]


def test_compensate_bad_inputs():
    t = np.arange(10) * 0.01
    r = np.zeros(10)
    with pytest.raises(ValueError, match="uniformly spaced"):
        jh.compensate(PAPER, t**2, r, limits=(0.0, 1.0))
    with pytest.raises(ValueError, match="lower < upper"):
        jh.compensate(PAPER, t, r, limits=(1.0, 0.0))
    with pytest.raises(ValueError, match="equal length"):
        jh.compensate(PAPER, t, r[:5], limits=(0.0, 1.0))
    with pytest.raises(ValueError, match="iterations"):
        jh.PerSampleInversion(iterations=0)
    with pytest.raises(ValueError, match="passes"):
        jh.OptimisedDrive(passes=-1)
    with pytest.raises(ValueError, match="rtol"):
        jh.OptimisedDrive(rtol=2.0)
    with pytest.raises(TypeError, match="method must be"):
        jh.compensate(PAPER, t, r, limits=(0.0, 1.0), method="bisect")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="jaxhyst model"):
        jh.compensate("piezo", t, r, limits=(0.0, 1.0))  # type: ignore[arg-type]


def test_compensation_compiles_once_per_length():
    path = _path(200.0)
    times = np.asarray(path.times)
    reference = np.asarray(jh.simulate(PAPER, path))
    jh.compensate(PAPER, times, reference, limits=(0.0, 5.0))
    with jax.log_compiles():
        import logging

        seen = []

        class _Catch(logging.Handler):
            def emit(self, record):
                seen.append(record.getMessage())

        handler = _Catch()
        logging.getLogger("jax").addHandler(handler)
        try:
            jh.compensate(
                PAPER.replace(k1=1.1 * PAPER.k1),
                times,
                0.9 * reference,
                limits=(0.0, 5.0),
            )
        finally:
            logging.getLogger("jax").removeHandler(handler)
    assert not [m for m in seen if "Compiling" in m and "_invert" in m]


def _model_and_reference(folder):
    path = jh.sample(jh.paper_u1(), 200.0)
    y = np.asarray(jh.simulate(PAPER, path))
    recording = jh.Recording(
        np.asarray(path.times),
        np.asarray(path.values),
        y,
        name="train",
        input_unit="V",
        output_unit="m",
    )
    jh.save_model(PAPER, folder / "model.json", recording=recording)
    t = np.arange(0, 5, 0.005)
    reference = 0.45 * y.max() * (1 - np.cos(2 * np.pi * 0.4 * t))
    np.savetxt(
        folder / "ref.csv",
        np.stack([t, reference], 1),
        delimiter=",",
        header="t,y",
        comments="",
    )
    return t, reference


def test_compensate_command_writes_the_drive_and_report(tmp_path, capsys):
    from jaxhyst._cli import main

    t, reference = _model_and_reference(tmp_path)
    out, report = tmp_path / "drive.csv", tmp_path / "rep" / "report.md"
    argv = ["compensate", str(tmp_path / "model.json"), str(tmp_path / "ref.csv")]
    assert main([*argv, "--out", str(out), "--report", str(report)]) == 0
    stdout = capsys.readouterr().out
    # Default limits: the training record's input range, 0-4 V.
    assert "drive limits 0 to 4" in stdout
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    assert out.read_text().splitlines()[0] == "t,u,y_predicted"
    np.testing.assert_allclose(table[:, 0], t)
    direct = jh.compensate(PAPER, t, reference, limits=(0.0, 4.0))
    np.testing.assert_allclose(table[:, 1], direct.drive, rtol=0, atol=1e-12)
    np.testing.assert_allclose(table[:, 2], direct.predicted, rtol=0, atol=1e-20)
    text = report.read_text()
    assert "| RMS |" in text and "compensation_drive.png" in text
    assert "| band | RMS | % of stroke | share of mean square |" in text
    assert (report.parent / "compensation_error.png").exists()
    assert "data:image/png;base64," in (report.parent / "report.html").read_text()
    # Outputs are not replaced without --force; a reference beyond the limits warns.
    assert main([*argv, "--out", str(out)]) == 2
    assert "already exists" in capsys.readouterr().err
    assert main([*argv, "--out", str(tmp_path / "d2.csv"), "--limits", "0,2"]) == 0
    assert "need a drive outside 0 to 2" in capsys.readouterr().err
    slow = ["--out", str(tmp_path / "d4.csv"), "--slew-limit", "0.5"]
    assert main([*argv, *slow, "--report", str(tmp_path / "r2" / "r.md")]) == 0
    assert "faster than --slew-limit 0.5 per s" in capsys.readouterr().err
    assert (
        "faster than the slew limit 0.5 per second"
        in (tmp_path / "r2" / "r.md").read_text()
    )
    assert main([*argv, "--out", str(tmp_path / "d3.csv"), "--limits", "2"]) == 2
    assert "LO,HI" in capsys.readouterr().err


def test_compensate_command_needs_limits_without_a_training_range(tmp_path, capsys):
    from jaxhyst._cli import main

    _model_and_reference(tmp_path)
    jh.save_model(PAPER, tmp_path / "bare.json")  # no recording: no input range
    argv = ["compensate", str(tmp_path / "bare.json"), str(tmp_path / "ref.csv")]
    assert main([*argv, "--out", str(tmp_path / "d.csv")]) == 2
    assert "--limits LO,HI" in capsys.readouterr().err
    assert not (tmp_path / "d.csv").exists()
    assert main([*argv, "--out", str(tmp_path / "d.csv"), "--limits", "0,4"]) == 0
