"""Model-free loop indicators (`jh.diagnosis.loop_indicators`): whether a cyclic
test's loops degrade and pinch, read without a model, and how that compares with the
effects a diagnosis named (`jh.diagnosis.compare_loops`).

The records are the package's own structural model (`StructuralBoucWen`) under a
FEMA 461-like ladder (`jh.synthetic.loading_protocol`), with its degradation or its
slip-lock pinching switched on, so each verdict is checked against loops whose
truth is known, and each measured loss against the simulated peaks themselves."""

import json
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxhyst as jh
from jaxhyst._diagnose._remainder import remainder
from jaxhyst._report import diagnosis_html, diagnosis_markdown
from jaxhyst._serialise import jsonable


X_Y, F_Y, ALPHA, N = 8.0, 300.0, 0.05, 1.5
PLAIN = jh.StructuralBoucWen(
    F_Y / ((1 - ALPHA) * X_Y),
    ALPHA,
    1.0,
    0.7 * X_Y**-N,
    0.3 * X_Y**-N,
    N,
    energy_scale=jnp.asarray(F_Y * 6 * X_Y),
    displacement_scale=jnp.asarray(6 * X_Y),
    force_scale=jnp.asarray(1.3 * F_Y),
)
DEGRADING = PLAIN.replace(strength_degradation=3.0)
PINCHED = PLAIN.replace(slip_length=1.0)


def _path(protocol: str, key: int = 0) -> jh.InputPath:
    path, _ = jh.synthetic.loading_protocol(
        jax.random.key(key), yield_displacement=X_Y, protocol=protocol, points=2000
    )
    return path


LADDER = _path("cyclic")  # 10 levels x 3 cycles, push first, to 4.2 x_y


def _record(model, path=LADDER, *, noise: float = 0.0, name: str = "test"):
    x = np.asarray(path.values)
    solver = jh.default_solver(model, jh.Recording.quasi_static(x, np.zeros_like(x)))
    y = np.asarray(jh.simulate(model, path, solver))
    if noise:
        rng = np.random.default_rng(7)
        y = y + noise * np.max(np.abs(y)) * rng.standard_normal(y.size)
    return jh.Recording.quasi_static(x, y, name=name, input_unit="mm", output_unit="kN")


@pytest.fixture(scope="module")
def records():
    return {
        name: _record(model, name=name)
        for name, model in (
            ("plain", PLAIN),
            ("degrading", DEGRADING),
            ("pinched", PINCHED),
        )
    }


def _direct_losses(recording):
    """From the simulated peaks alone: per direction, 1 - the force at the
    second cycle's peak over the first's at each level (the ladder repeats its peaks
    exactly, on samples), and 1 - the force at the largest displacement over the
    largest force at a peak."""
    x, y = np.asarray(recording.u), np.asarray(recording.y)
    peaks = recording.reversals()
    cyclic, envelope = [], []
    for sign in (1.0, -1.0):
        mine = [k for k in peaks if np.sign(x[k]) == sign]
        for a, b, c in zip(mine, mine[1:], [None, *mine[:-1]]):
            first = c is None or not np.isclose(x[c], x[a])
            if first and np.isclose(x[b], x[a]):
                cyclic.append(1 - y[b] / y[a])
        forces = sign * y[mine]
        envelope.append(1 - forces[np.argmax(sign * x[mine])] / np.max(forces))
    return float(np.median(cyclic)), len(cyclic), max(envelope)


def test_a_plain_bouc_wen_test_neither_degrades_nor_pinches(records):
    loops = jh.diagnosis.loop_indicators(records["plain"])
    assert isinstance(loops, jh.diagnosis.LoopIndicators)
    assert loops.degradation.answer == "no", loops.degradation.reason
    assert loops.pinching.answer == "no", loops.pinching.reason
    assert len(loops.levels) == 10 and {level.cycles for level in loops.levels} == {3}
    assert abs(loops.strength_loss) < 0.01
    # Past yield a full loop keeps most of its force at zero displacement.
    assert loops.zero_force_ratio > 0.6 and loops.energy_ratio > 0.4


def test_a_degrading_test_degrades_by_what_its_peaks_say(records):
    recording = records["degrading"]
    loops = jh.diagnosis.loop_indicators(recording)
    cyclic, pairs, envelope = _direct_losses(recording)
    assert pairs == 20  # 10 levels, both directions
    assert loops.degradation.answer == "yes", loops.degradation.reason
    assert loops.strength_loss == pytest.approx(cyclic, abs=2e-3)
    assert max(loops.envelope_loss) == pytest.approx(envelope, abs=0.02)
    assert envelope > 0.3  # the Baber-Wen degradation loses strength past the peak
    assert "below the test's peak force" in loops.degradation.reason
    plain = jh.diagnosis.loop_indicators(records["plain"])
    assert loops.strength_loss > plain.strength_loss + 0.02


def test_a_cyclic_loss_at_equal_displacement_is_measured_as_lost():
    # The plain loops with every later cycle of a level 15 % weaker (scaled from
    # the sample after the reversal that starts it): the indicators must read 15 %
    # on the second cycles and 28 % (1 - 0.85^2) on the third.
    recording = _record(PLAIN)
    x, y = np.asarray(recording.u), np.asarray(recording.y).copy()
    peaks = recording.reversals()
    scale = np.ones_like(y)
    for start, a, b in zip(peaks[1::2], peaks[0::2], peaks[2::2]):
        if np.isclose(x[a], x[b]):  # a repeated cycle starts at `start`
            scale[start + 1 :] *= 0.85
        else:
            scale[start + 1 :] = 1.0
    weakened = jh.Recording.quasi_static(x, y * scale, name="weakened")
    loops = jh.diagnosis.loop_indicators(weakened)
    assert loops.degradation.answer == "yes", loops.degradation.reason
    assert loops.strength_loss == pytest.approx(0.15, abs=0.01)
    assert loops.last_strength_loss == pytest.approx(1 - 0.85**2, abs=0.015)
    assert "15 % less force at the same displacement" in loops.degradation.reason
    assert "median of 10 levels" in loops.degradation.reason


def test_a_pinched_test_pinches(records):
    loops = jh.diagnosis.loop_indicators(records["pinched"])
    plain = jh.diagnosis.loop_indicators(records["plain"])
    assert loops.pinching.answer == "yes", loops.pinching.reason
    assert loops.zero_force_ratio < 0.3 and loops.energy_ratio < 0.3
    assert loops.zero_force_ratio < 0.5 * plain.zero_force_ratio
    # Level by level past yield, the slip leaves far less force at zero
    # displacement than the plain loop at the same amplitude (under the same
    # ladder), and the gap opens with the excursion.
    gaps = [
        full.zero_force_ratio - thin.zero_force_ratio
        for thin, full in zip(loops.levels, plain.levels, strict=True)
        if full.amplitude > 1.5 * X_Y
    ]
    assert len(gaps) == 4 and min(gaps) > 0.3 and gaps[-1] > gaps[0]
    assert loops.degradation.answer == "no"


def test_one_per_cent_noise_does_not_flip_a_clear_verdict(records):
    for name, model in (
        ("plain", PLAIN),
        ("degrading", DEGRADING),
        ("pinched", PINCHED),
    ):
        clean = jh.diagnosis.loop_indicators(records[name])
        noisy = jh.diagnosis.loop_indicators(_record(model, noise=0.01))
        assert noisy.degradation.answer == clean.degradation.answer, name
        assert noisy.pinching.answer == clean.pinching.answer, name
        assert noisy.reversals == clean.reversals, name  # noise makes no reversal
        assert noisy.strength_loss == pytest.approx(clean.strength_loss, abs=0.02)
        assert noisy.zero_force_ratio == pytest.approx(clean.zero_force_ratio, abs=0.03)


def test_a_record_too_noisy_or_backwards_cannot_tell_and_says_why(records):
    noisy = jh.diagnosis.loop_indicators(_record(DEGRADING, noise=0.1))
    for verdict in (noisy.degradation, noisy.pinching):
        assert verdict.answer == "cannot tell"
        assert "too noisy to read its loops" in verdict.reason
    plain = records["plain"]
    flipped = jh.Recording.quasi_static(plain.u, -np.asarray(plain.y))
    backwards = jh.diagnosis.loop_indicators(flipped)
    assert backwards.pinching.answer == "cannot tell"
    assert "does not follow the displacement" in backwards.pinching.reason
    # Pure noise is no loop either.
    rng = np.random.default_rng(3)
    scatter = jh.Recording.quasi_static(rng.standard_normal(500), rng.normal(size=500))
    assert jh.diagnosis.loop_indicators(scatter).degradation.answer == "cannot tell"


def test_an_earthquake_like_history_cannot_tell_a_cyclic_loss():
    loops = jh.diagnosis.loop_indicators(_record(PLAIN, _path("earthquake")))
    assert loops.repeated_levels < 2
    assert loops.degradation.answer == "cannot tell"
    assert "no two cycles reach the same displacement" in loops.degradation.reason
    assert math.isnan(loops.degradation.measure) or loops.degradation.measure < 0.2


def test_a_monotonic_record_cannot_tell_either_and_never_raises():
    x = np.linspace(0.0, 40.0, 400)
    monotonic = jh.Recording.quasi_static(x, 30.0 * np.tanh(x / 8.0), name="push")
    loops = jh.diagnosis.loop_indicators(monotonic)
    for verdict in (loops.degradation, loops.pinching):
        assert verdict.answer == "cannot tell"
        assert "reverses 0 times" in verdict.reason
    assert loops.cycles == () and loops.levels == ()
    # A constant force: no loop either.
    flat = jh.Recording.quasi_static(np.sin(np.linspace(0, 20, 400)), np.ones(400))
    assert jh.diagnosis.loop_indicators(flat).pinching.answer == "cannot tell"


def test_a_non_recording_is_a_type_error_naming_the_argument():
    with pytest.raises(TypeError, match="recording must be a jaxhyst Recording"):
        jh.diagnosis.loop_indicators(np.zeros((2, 100)))  # type: ignore[arg-type]


def test_the_comparison_says_where_names_and_loops_disagree_and_why(records):
    pinched = jh.diagnosis.loop_indicators(records["pinched"])
    found = {
        a.effect: a
        for a in jh.diagnosis.compare_loops(
            ("degradation",),
            pinched,
            not_named={"pinching": "the held-out cycles did not support it"},
        )
    }
    degradation, pinching = found["degradation"], found["pinching"]
    assert degradation.named and degradation.loops == "no"
    assert degradation.agree is False
    assert "degradation named, but the loops do not degrade" in degradation.statement
    assert "not a loss of strength at equal displacement" in degradation.statement
    assert not pinching.named and pinching.loops == "yes" and pinching.agree is False
    assert "the loops pinch (force at zero displacement" in pinching.statement
    assert "the held-out cycles did not support it" in pinching.statement
    undecided = jh.diagnosis.compare_loops((), pinched, undecided=("pinching",))
    assert "left it undecided" in undecided[1].statement
    agreed = jh.diagnosis.compare_loops(("pinching",), pinched)
    assert [a.agree for a in agreed] == [True, True]


def _diagnosis(recording, family) -> jh.Diagnosis:
    """A diagnosis made by hand (no fit): the base model named pinching."""
    y = np.asarray(recording.y)
    predicted = np.asarray(jh.predict(PLAIN, recording))
    metrics = jh.error_metrics(y, predicted)
    heldout = np.zeros(y.size, bool)
    heldout[::3] = True
    validation = jh.diagnosis.Validation(
        heldout_rmse_before=2.0,
        heldout_rmse_after=1.0,
        fit_rmse_before=2.0,
        fit_rmse_after=1.0,
        heldout_margin_mse=0.1,
        heldout_resolution_mse=0.1,
        effective_samples_heldout=50.0,
        bic_change=-10.0,
        score_statistic=30.0,
        score_dof=2,
        log10_p=-6.0,
        accepted=True,
    )
    finding = jh.Finding(
        "pinching", "made-up", "near zero force", 30.0, {}, metrics, metrics, validation
    )
    return jh.Diagnosis(
        recording=recording.name,
        samples=recording.num_samples,
        family=family.name,
        base_name=family.base_name,
        base_model=PLAIN,
        final_model=PLAIN,
        baseline=metrics,
        final=metrics,
        findings=[finding],
        unexplained=[],
        rounds=[],
        ambiguities=[],
        advice=[],
        steps=[],
        noise_sigma=1.0,
        noise={"sigma": 1.0, "lag1_autocorrelation": 0.0, "effective_samples": 100.0},
        location={},
        base_predicted=predicted,
        final_predicted=predicted,
        heldout=heldout,
        holdout_description=family.holdout_description,
        holdout_fraction=1 / 3,
        final_parameters={},
        exports={},
        seconds=0.0,
        remainder=remainder(recording, y - predicted, heldout=heldout),
        loops=family.loop_indicators(recording),
    )


def test_the_structural_diagnosis_carries_the_loops_into_its_json_and_report(
    records, tmp_path
):
    family = jh.families.StructuralFamily()
    assert jh.families.PiezoFamily().loop_indicators(records["pinched"]) is None
    diagnosis = _diagnosis(records["pinched"], family)
    data = json.loads(json.dumps(jsonable(diagnosis.to_dict()), allow_nan=False))
    loops = data["loops"]
    assert loops["pinching"]["answer"] == "yes"
    assert len(loops["levels"]) == 10 and len(loops["cycles"]) == 30
    assert {a["effect"]: a["agree"] for a in loops["agreement"]} == {
        "degradation": True,
        "pinching": True,
    }
    report = diagnosis_markdown(diagnosis, records["pinched"], tmp_path / "r.md", {})
    section = report.split("## The loops, without a model")[1].split("\n## ")[0]
    assert "**Do they pinch? yes**: at the largest amplitudes" in section
    assert "| level | amplitude [mm] |" in section
    assert section.count("\n| ") == 11  # the header and ten levels
    assert "**agree**: pinching named, and the loops pinch" in section
    html = diagnosis_html(diagnosis, records["pinched"], tmp_path / "r.html", {})
    assert "The loops, without a model" in html and "<strong>agree</strong>" in html
    # Other families: the key is there, null.
    piezo = _diagnosis(records["pinched"], jh.families.PiezoFamily())
    assert piezo.to_dict()["loops"] is None and piezo.loop_agreement == ()
