import jax
import numpy as np
import pytest
from helpers import assert_the_chain_adds_up_and_findings_are_keyed

import jaxhyst as jh


def _case(effects, seed=0, noise="white", duration=10.0, rate=500.0, size=8.0):
    return jh.synthetic.concealed_recording(
        effects,
        key=jax.random.key(seed),
        duration=duration,
        rate=rate,
        noise=noise,
        size_sigmas=size,
    )


def test_catalogue_names_are_stable_and_nested():
    assert jh.families.EFFECT_NAMES == (
        "asymmetry",
        "input_bias",
        "rate_dependence",
        "creep",
        "dynamics",
        "drift",
    )
    # Every effect's parameters exist on the extended model and default to "off".
    base = jh.PiezoBoucWen(1.0, 0.3, -1.0, 0.002, -0.001, 1.5)
    path = jh.sample(jh.paper_u1(), 100.0)
    extended = jh.ExtendedPiezo.around(base, path)
    np.testing.assert_allclose(
        jh.simulate(extended, path), jh.simulate(base, path), rtol=0, atol=1e-12
    )
    for effect in jh.families.CATALOGUE.values():
        for name in effect.parameters:
            assert name in jh.ExtendedPiezo.parameter_names


def test_locate_finds_branch_and_trend():
    t = np.linspace(0, 10, 5001)
    u = 50 * (1 - np.cos(2 * np.pi * 0.5 * t))
    udot = np.gradient(u, t)
    branch = np.where(udot > 0, 1.0, -1.0)
    where = jh.families.locate(t, u, branch)
    assert where["ascending"]["mean"] > 0.9 and where["descending"]["mean"] < -0.9
    trend = jh.families.locate(t, u, 0.1 * t)
    assert trend["slow_trend_rms"] > 0.9 * trend["overall_rms"]


def test_clean_recording_flags_nothing():
    case = _case((), seed=1)
    diagnosis = jh.diagnose(case.recording, key=jax.random.key(0))
    assert diagnosis.findings == []
    assert diagnosis.final_rmse < 1.1 * case.sigma
    report = diagnosis.to_dict()
    for key in ("recording", "samples", "model", "noise", "baseline", "findings"):
        assert key in report
    assert report["final"]["model"] == "piezo" and report["ambiguities"] == []


@pytest.mark.slow
def test_clean_coloured_noise_flags_nothing():
    case = _case((), seed=2, noise="coloured")
    diagnosis = jh.diagnose(case.recording, key=jax.random.key(0))
    assert diagnosis.findings == []


@pytest.mark.slow
@pytest.mark.parametrize("effect", ["asymmetry", "creep"])
def test_concealed_effect_is_named_and_fixed(effect):
    case = _case((effect,), seed=3)
    diagnosis = jh.diagnose(case.recording, key=jax.random.key(0))
    assert diagnosis.effects == (effect,)
    assert diagnosis.final_rmse < 1.3 * case.sigma
    finding = diagnosis.findings[0]
    assert finding.after["rmse"] < finding.before["rmse"]
    assert finding.validation.accepted


def test_diagnose_rejects_bad_input():
    with pytest.raises(TypeError, match="Recording"):
        jh.diagnose(np.zeros(10), key=jax.random.key(0))  # type: ignore[arg-type]
    case = _case((), duration=2.0, rate=100.0)
    with pytest.raises(ValueError, match="holdout_fraction"):
        jh.diagnose(case.recording, key=jax.random.key(0), holdout_fraction=0.9)


def test_near_miss_overlapping_an_adopted_effect_is_reported():
    from jaxhyst._diagnose._ambiguity import standing_in

    t = np.linspace(0.0, 45.0, 4501)
    slow_mode = np.stack([1 - np.exp(-t / 30.0)], axis=1)  # an adopted creep mode
    thermal = np.stack([1 - np.exp(-t / 22.0), t / 45.0], axis=1)
    unrelated = np.stack([np.sin(2 * np.pi * t)], axis=1)

    def result(effect, after, accepted=False, resolution=0.01, bic=-10.0):
        validation = jh.diagnosis.Validation(
            heldout_rmse_before=1.05,
            heldout_rmse_after=after,
            fit_rmse_before=1.0,
            fit_rmse_after=1.0,
            heldout_margin_mse=0.05,
            heldout_resolution_mse=resolution,
            effective_samples_heldout=1000.0,
            bic_change=bic,
            score_statistic=100.0,
            score_dof=2,
            log10_p=-10.0,
            accepted=accepted,
        )
        return (effect, validation)

    projected = {"drift": thermal, "asymmetry": unrelated}
    adopted = {"creep": slow_mode}
    near = [result("drift", 1.03)]  # 4 % gain: beyond its noise, under 5 %
    messages = standing_in(near, projected, adopted)
    assert len(messages) == 1
    statement = messages[0].statement
    assert statement.startswith("drift may also be present") and "creep" in statement
    assert messages[0].undecided == ("drift",)
    # Not reported: a gain within the noise, a worse BIC, an accepted candidate,
    # or a signature unlike any adopted effect's.
    assert (
        standing_in([result("drift", 1.03, resolution=0.1)], projected, adopted) == []
    )
    assert standing_in([result("drift", 1.03, bic=5.0)], projected, adopted) == []
    assert standing_in([result("drift", 1.0, accepted=True)], projected, adopted) == []
    assert standing_in([result("asymmetry", 1.03)], projected, adopted) == []


def test_runner_up_swapped_in_keeps_its_refitted_parameters():
    base = jh.PiezoBoucWen(1.0, 0.3, -1.0, 0.002, -0.001, 1.5)
    path = jh.sample(jh.paper_u1(), 100.0)
    current = jh.ExtendedPiezo.around(base, path).replace(phi=0.01, eps=0.02)
    source = jh.ExtendedPiezo.around(base, path).with_dynamics(40.0, 0.3)
    swapped = jh.effects.Dynamics().take_from(
        jh.effects.InputBias().switch_off(current), source
    )
    assert swapped.dynamic and float(swapped.natural_frequency) == 40.0
    assert float(swapped.phi) == 0.0 and float(swapped.eps) == 0.02
    back = jh.effects.InputBias().take_from(
        jh.effects.Dynamics().switch_off(swapped), current
    )
    assert not back.dynamic and float(back.phi) == 0.01
    np.testing.assert_allclose(
        jh.simulate(back, path), jh.simulate(current, path), rtol=0, atol=1e-12
    )


def test_creep_evidence_without_holds_reads_as_words_not_nan():
    t = np.linspace(0.0, 5.0, 5001)
    u = 75 * np.sin(2 * np.pi * t)
    where = jh.families.locate(t, u, np.random.default_rng(0).standard_normal(t.size))
    where["after_hold"]["relative"] = float("nan")  # as `locate` gives without holds
    text = jh.effects.Creep().evidence(where, None)
    assert "nan" not in text and "no holds" in text


def test_a_large_concealed_effect_is_named_on_a_short_record():
    # The piezo family's positive check under the default policy (slow, run by
    # .ci/run): a diagnosis that never names anything fails.
    case = _case(("drift",), seed=3)
    diagnosis = jh.diagnose(case.recording, key=jax.random.key(0))
    assert diagnosis.effects == ("drift",)
    assert diagnosis.final_rmse < 1.3 * case.sigma
    finding = diagnosis.findings[0]
    assert finding.validation.accepted and finding.validation.heldout_gain > 0.3
    report = diagnosis.to_dict()
    assert report["final"]["model"] == "piezo+drift"
    assert report["unexplained"] == []
    assert_the_chain_adds_up_and_findings_are_keyed(diagnosis)


def test_unexplained_structure_is_judged_against_the_residuals_own_noise():
    from scipy.signal import lfilter

    from jaxhyst._diagnose._unexplained import unexplained_structure

    case = jh.synthetic.concealed_recording(
        (), key=jax.random.key(0), duration=12.0, rate=500.0
    )
    recording, family = case.recording, jh.families.PiezoFamily()
    fit = family.holdout(recording, 0.2)
    policy = jh.families.AdoptionPolicy()

    def coloured(seed, coefficient=0.9):
        shocks = np.random.default_rng(seed).standard_normal(
            recording.num_samples + 500
        )
        return lfilter([1.0], [1.0, -coefficient], shocks)[500:]

    # Coloured noise alone: nothing (the probes' gains on it are what the
    # residual's own AR noise gives).
    for seed in range(3):
        assert (
            unexplained_structure(
                recording, family, coloured(seed), fit, policy, seed=seed
            )
            == []
        )
    # A static function of the input, as large as the noise, that no effect
    # removed: a loop-shaped mismatch, the same on both directions of motion.
    u = np.asarray(recording.u)
    level = (u - u.mean()) / np.std(u)
    noise = coloured(7)
    static = np.std(noise) * (level**3 - 3 * level) / np.std(level**3 - 3 * level)
    found = unexplained_structure(
        recording, family, noise + static, fit, policy, seed=7
    )[0]
    assert "function of the input's level and direction" in found.description
    assert "the same on both directions of motion" in found.resembles
    assert found.heldout_gain > 0.3
    assert "could not decide" not in found.description
    # Effects the record could not decide on are named with it (part of the
    # structure may be theirs).
    with_undecided = unexplained_structure(
        recording,
        family,
        noise + static,
        fit,
        policy,
        seed=7,
        undecided=("creep", "drift"),
    )[0]
    assert (
        "the record could not decide whether creep or drift are present"
        in with_undecided.description
    )


def _oversampled(series: np.ndarray, density: int, rng) -> np.ndarray:
    grid = np.linspace(0, 1, series.size)
    fine = np.linspace(0, 1, series.size * density)
    return np.interp(fine, grid, series) + 1e-3 * rng.standard_normal(fine.size)


def test_effective_samples_read_across_strides_do_not_fall_with_density():
    # A smooth misfit (a high-passed random walk) sampled 4 to 64 times more
    # densely: at full density the AR(2) count jumps around and collapses; read
    # across strides it stays put.
    from jaxhyst._diagnose._score import NoiseModel

    rng = np.random.default_rng(0)
    walk = np.cumsum(rng.standard_normal(1000))
    walk -= np.convolve(walk, np.ones(101) / 101, "same")
    counts, dense_counts = [], []
    for density in (4, 16, 64):
        series = _oversampled(walk, density, rng)
        dense = NoiseModel.estimate(series)
        strided = NoiseModel.estimate(series, across_strides=True)
        dense_counts.append(dense.effective_ratio * series.size)
        counts.append(strided.effective_ratio * series.size)
    assert max(counts) < 1.5 * min(counts)
    assert min(dense_counts) < 0.5 * min(counts)


@pytest.mark.parametrize("coefficient", [0.0, 0.88])
def test_effective_samples_across_strides_leave_ar_noise_alone(coefficient):
    from jaxhyst._diagnose._score import NoiseModel

    rng = np.random.default_rng(1)
    shocks = rng.standard_normal(20000)
    noise = np.zeros_like(shocks)
    for i in range(1, noise.size):
        noise[i] = coefficient * noise[i - 1] + shocks[i]
    dense = NoiseModel.estimate(noise).effective_ratio
    strided = NoiseModel.estimate(noise, across_strides=True).effective_ratio
    expected = (1 - coefficient) / (1 + coefficient)
    assert strided == pytest.approx(dense, rel=0.1)
    assert strided == pytest.approx(expected, rel=0.1)


def test_only_the_structural_family_reads_its_noise_across_strides():
    assert jh.families.StructuralFamily().default_policy().noise_across_strides
    assert not jh.families.PiezoFamily().default_policy().noise_across_strides
    assert not jh.families.DamperFamily().default_policy().noise_across_strides
