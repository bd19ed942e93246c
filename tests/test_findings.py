"""Findings an engineer can trust: standard errors, rivals, advice inputs, progress."""

import math
import re

import numpy as np
import pytest

import jaxhyst as jh
from jaxhyst._diagnose._ambiguity import cannot_tell_rivals
from jaxhyst._diagnose._diagnose import _moved
from jaxhyst._diagnose._probes import cyclic_probes, dominant_frequency, piezo_probes
from jaxhyst._diagnose._progress import Progress
from jaxhyst._diagnose._results import Finding, Rival
from jaxhyst._diagnose._uncertainty import standard_errors


def _ar1(rng, n, rho):
    e = rng.standard_normal(n)
    out = np.empty(n)
    out[0] = e[0]
    for i in range(1, n):
        out[i] = rho * out[i - 1] + math.sqrt(1 - rho**2) * e[i]
    return out


def test_standard_errors_match_least_squares_for_white_noise():
    rng = np.random.default_rng(0)
    x = np.linspace(0, 1, 4000)
    jac = np.stack([x, np.ones_like(x)], axis=1)
    residual = 0.1 * rng.standard_normal(x.size)
    se = standard_errors(jac, residual)
    sigma2 = np.sum(residual**2) / (x.size - 2)
    expected = np.sqrt(np.diag(sigma2 * np.linalg.inv(jac.T @ jac)))
    # White noise: N_eff ~ N, so within a few percent of the textbook formula.
    np.testing.assert_allclose(se, expected, rtol=0.1)


def test_standard_errors_grow_for_a_correlated_residual():
    rng = np.random.default_rng(1)
    x = np.linspace(0, 1, 4000)
    jac = np.stack([x, np.ones_like(x)], axis=1)
    white = standard_errors(jac, 0.1 * rng.standard_normal(x.size))
    smooth = standard_errors(jac, 0.1 * _ar1(rng, x.size, 0.95))
    # AR(1) with rho = 0.95: N / N_eff ~ (1 + rho) / (1 - rho) = 39, so ~6x.
    assert np.all(smooth > 3 * white)


def test_standard_errors_are_nan_for_what_the_record_cannot_determine():
    x = np.linspace(0, 1, 500)
    jac = np.stack([x, 2 * x, np.ones_like(x)], axis=1)  # columns 0 and 1 alias
    se = standard_errors(jac, 0.01 * np.random.default_rng(2).standard_normal(500))
    assert np.isnan(se[0]) and np.isnan(se[1]) and np.isfinite(se[2])


def _sine_recording(frequency=1.0, duration=10.0, rate=200.0):
    t = np.arange(0, duration, 1 / rate)
    u = 50 * (1 - np.cos(2 * np.pi * frequency * t))
    return jh.Recording(t, u, 0.01 * u, input_unit="V", output_unit="um")


def test_piezo_probes_span_the_record_and_vary_what_it_does_not():
    recording = _sine_recording()
    assert dominant_frequency(recording) == pytest.approx(1.0)
    probes = piezo_probes(recording)
    assert len(probes) >= 4
    low, high = recording.u.min(), recording.u.max()
    for probe in probes:
        values = np.asarray(probe.path.values)
        assert values.size == recording.num_samples
        assert values.min() >= low - 1e-9 and values.max() <= high + 1e-9
        assert probe.description
    fast = jh.Recording(recording.t, np.asarray(probes[0].path.values), recording.y)
    assert dominant_frequency(fast) == pytest.approx(10.0, rel=0.05)
    assert "10 Hz" in probes[0].description
    staircase = np.asarray(probes[-1].path.values)
    held = np.abs(np.diff(staircase)) < 1e-12
    assert held.mean() > 0.5  # mostly holds


def test_cyclic_probes_reach_the_amplitudes_they_name():
    x = 2.0 * np.sin(np.linspace(0, 6 * np.pi, 900))
    recording = jh.Recording.quasi_static(x, 3 * x)
    probes = cyclic_probes(recording)
    repeated, growing, one_sided = (np.asarray(p.path.values) for p in probes[:3])
    reach = np.abs(recording.u).max()
    assert repeated.max() == pytest.approx(reach, rel=1e-9)
    assert growing.max() == pytest.approx(1.5 * reach, rel=1e-9)
    half = one_sided.size // 2
    assert one_sided[:half].min() >= -1e-9 and one_sided[half:].max() <= 1e-9


def test_progress_prints_stages_to_stderr_only_when_asked(capsys):
    Progress(True).say("round 1: scoring asymmetry")
    Progress(False).say("silent")
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "round 1: scoring asymmetry" in captured.err and "silent" not in captured.err
    assert captured.err.startswith("[diagnose")


def test_a_finding_is_decided_only_when_every_rival_lost_beyond_the_resolution():
    validation = jh.diagnosis.Validation(
        1.0, 0.5, 1.0, 0.5, 0.1, 0.1, 100.0, -5.0, 50.0, 1, -9.0, True
    )
    finding = Finding("creep", "", "", 50.0, {}, {}, {}, validation)
    lost = Rival("drift", 0.7, 8.0)
    close = Rival("rate_dependence", 0.51, 1.2)
    assert dataclass_replace(finding, rivals=(lost,)).decided
    assert not dataclass_replace(finding, rivals=(lost, close)).decided
    record = dataclass_replace(finding, rivals=(lost, close)).to_dict()
    assert record["rivals"][1] == {
        "effect": "rate_dependence",
        "heldout_rmse": 0.51,
        "margin_sigma": 1.2,
    }
    ambiguity = cannot_tell_rivals(
        "creep", [close], 0.5, kept_because="its held-out error is the lowest of them"
    )
    assert ambiguity.undecided == ("creep", "rate_dependence")
    assert "cannot tell creep from rate_dependence" in ambiguity.statement
    assert "lost by 1.2 standard errors" in ambiguity.statement
    assert "kept for the fit (its held-out error is the lowest of them)" in (
        ambiguity.statement
    )


def dataclass_replace(obj, **changes):
    import dataclasses

    return dataclasses.replace(obj, **changes)


def test_a_large_move_since_adoption_is_flagged_and_a_small_one_is_not():
    units = {"phi": "s"}
    moved = _moved({"phi": 0.133}, {"phi": 0.262}, {"phi": 0.004}, units, ["creep"])
    assert moved is not None
    assert "phi 0.133 -> 0.262 s" in moved and "32 standard errors" in moved
    assert "creep" in moved
    # Within the noise (a poorly determined value), or a small share: no flag.
    assert _moved({"phi": 0.133}, {"phi": 0.262}, {"phi": 0.1}, units, []) is None
    assert _moved({"phi": 0.133}, {"phi": 0.14}, {"phi": 1e-4}, units, []) is None
    assert "standard errors" not in (
        _moved({"phi": 0.133}, {"phi": 0.262}, {"phi": float("nan")}, units, []) or ""
    )


def test_a_drift_that_is_only_an_offset_reads_as_an_offset():
    units = dict.fromkeys(("offset", "trend", "curvature", "wander"), "um")
    values = {"offset": -1.6, "trend": 0.01, "curvature": -0.02, "wander": 0.003}
    errors = {"offset": 0.02, "trend": 0.05, "curvature": 0.03, "wander": 0.01}
    text = jh.effects.Drift().reading(values, errors, units)
    assert text.startswith("a constant offset of the output, -1.6")
    assert "raises" not in text and "curvature puts" not in text
    # A trend beyond its standard errors is named.
    errors["trend"] = 0.001
    text = jh.effects.Drift().reading(values, errors, units)
    assert "a linear trend raises it by 0.02" in text and "constant offset" not in text


def test_drift_evidence_names_an_offset_at_rest_only_when_the_numbers_show_one():
    t = np.linspace(0.0, 10.0, 10001)
    u = np.where(t < 3.0, 0.0, 75 * (1 - np.cos(2 * np.pi * (t - 3.0))))
    noise = 0.01 * np.random.default_rng(3).standard_normal(t.size)
    offset = jh.families.locate(t, u, np.where(t < 3.0, -1.6, 0.0) + noise)
    text = jh.effects.Drift().evidence(offset, None)
    assert re.search(r"near-constant -1\.(59|6)\b", text) and "sensor zero" in text
    plain = jh.families.locate(t, u, noise)
    assert "near-constant" not in jh.effects.Drift().evidence(plain, None)


def test_a_gain_confined_to_the_fitted_samples_is_reported_as_cannot_tell():
    from jaxhyst._diagnose._ambiguity import confined

    def validation(fit_after, held_after, bic=-50.0, accepted=False):
        return jh.diagnosis.Validation(
            heldout_rmse_before=0.10,
            heldout_rmse_after=held_after,
            fit_rmse_before=0.16,
            fit_rmse_after=fit_after,
            heldout_margin_mse=5e-4,
            heldout_resolution_mse=5e-4,
            effective_samples_heldout=500.0,
            bic_change=bic,
            score_statistic=3e4,
            score_dof=3,
            log10_p=-300.0,
            accepted=accepted,
        )

    # A switch-on transient fixed on the fitted samples, nothing on the held-out.
    found = confined([("rate_dependence", validation(0.11, 0.0999))])
    assert len(found) == 1 and found[0].undecided == ("rate_dependence",)
    assert "lowered the error on the fitted samples by 53%" in found[0].statement
    # Not when the fitted gain is small, the criterion disagrees, the held-out data
    # confirm it, it was accepted, or it is already undecided.
    assert confined([("creep", validation(0.159, 0.0999))]) == []
    assert confined([("creep", validation(0.11, 0.0999, bic=5.0))]) == []
    assert confined([("creep", validation(0.11, 0.09))]) == []
    assert confined([("creep", validation(0.11, 0.104))]) == []  # worse held out
    assert confined([("creep", validation(0.11, 0.0999, accepted=True))]) == []
    assert (
        confined([("creep", validation(0.11, 0.0999))], already=frozenset({"creep"}))
        == []
    )
