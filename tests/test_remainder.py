"""What is left (`jaxhyst._diagnose._remainder`): the worst span, branch and event
of a final residual, and whether the rest is noise-like."""

import json

import numpy as np
import pytest

import jaxhyst as jh
from jaxhyst._diagnose._remainder import (
    LAG1_NOISE_LIMIT,
    SPAN_NOISE_LIMIT,
    START,
    START_RATE,
    SWITCH_ON,
    remainder,
)
from jaxhyst._serialise import jsonable


DT = 0.01
T = np.arange(3001) * DT  # 30 s at 100 Hz
SIGMA = 1e-8


def _recording(u, *, unit="m"):
    return jh.Recording(T, u, 1e-6 * u, name="synthetic", output_unit=unit)


def _noise(seed=0):
    return SIGMA * np.random.default_rng(seed).standard_normal(T.size)


@pytest.fixture(scope="module")
def held_then_driven():
    """5 s at rest, then the paper's u1 from 5 s on."""
    return _recording(np.where(T < 5, 0.0, 2 - 2 * np.cos(0.2 * np.pi * (T - 5))))


def test_switch_on_transient_after_a_hold(held_then_driven):
    transient = np.where(T >= 5, 20 * SIGMA * np.exp(-(T - 5) / 0.4), 0.0)
    left = remainder(held_then_driven, _noise() + transient)
    assert left.event == SWITCH_ON
    assert left.span_start == pytest.approx(5.0, abs=2 * DT)
    assert left.span_end - left.span_start == pytest.approx(1.5, abs=2 * DT)
    assert left.span_share > 0.5
    assert left.span_ratio > SPAN_NOISE_LIMIT
    assert left.verdict == "structured"
    sentence = left.text(1e6, "µm")
    assert sentence.startswith(
        f"The final model misses most in {left.span_start:.4g}-"
        f"{left.span_end:.4g} s (the switch-on transient): RMS "
        f"{1e6 * left.span_rms:.4g} µm"
    )
    assert f"{100 * left.span_share:.1f} % of the squared error" in sentence
    assert f"{left.span_ratio:.1f}x the overall RMS" in sentence


@pytest.mark.parametrize(
    "phase, event",
    [(0.0, SWITCH_ON), (0.3, START)],  # from rest; a window cut mid-motion
)
def test_a_transient_at_the_first_sample(phase, event):
    u = 2 - 2 * np.cos(0.2 * np.pi * T + 2 * np.pi * phase)
    transient = 20 * SIGMA * np.exp(-T / 0.4)
    left = remainder(_recording(u), _noise(6) + transient)
    assert left.event == event
    assert left.span_first == 0
    if event == START:
        rate = 0.4 * np.pi * np.sin(2 * np.pi * phase) / (0.4 * np.pi)
        assert left.start_rate == pytest.approx(rate, rel=0.02)
        assert "which begins mid-motion: the input moves at " in left.sentence
        assert f"{100 * left.start_rate:.2g} % of its peak rate" in left.sentence
    else:
        assert left.start_rate < START_RATE
        assert "(the switch-on transient)" in left.sentence


def test_a_transient_in_the_middle_is_not_the_switch_on(held_then_driven):
    bump = 20 * SIGMA * np.exp(-(((T - 18) / 0.3) ** 2))
    left = remainder(held_then_driven, _noise() + bump)
    assert left.event is None
    assert left.span_start < 18 < left.span_end
    assert "switch-on" not in left.sentence


def test_white_noise_is_noise_like_and_names_no_event(held_then_driven):
    left = remainder(held_then_driven, _noise(1))
    assert left.verdict == "noise-like" and left.noise_like
    assert left.event is None
    assert abs(left.lag1_autocorrelation) < 0.1
    assert left.effective_fraction > 0.8
    assert left.span_ratio < SPAN_NOISE_LIMIT
    assert left.sentence.startswith("What is left looks like noise: ")
    assert "switch-on" not in left.sentence and "structured" not in left.sentence


def test_a_slow_residual_is_structured_by_its_autocorrelation(held_then_driven):
    slow = 3 * SIGMA * np.sin(2 * np.pi * T / 7)
    left = remainder(held_then_driven, _noise(2) + slow)
    assert left.lag1_autocorrelation > LAG1_NOISE_LIMIT
    assert left.span_ratio < SPAN_NOISE_LIMIT  # spread out, yet structured
    assert left.verdict == "structured"
    assert f"lag-1 autocorrelation {left.lag1_autocorrelation:.3g}" in left.sentence
    assert "that span is" not in left.sentence  # not a reason here: not claimed


def test_the_descending_branch_is_named():
    u = 2 - 2 * np.cos(0.2 * np.pi * T)
    falling = np.gradient(u) < 0
    residual = _noise(3) * np.where(falling, 4.0, 1.0)
    left = remainder(_recording(u), residual)
    assert left.branch == "descending"
    assert left.branch_rms == pytest.approx(np.sqrt(np.mean(residual[falling] ** 2)))
    assert left.branch_percent == pytest.approx(
        100 * left.branch_rms / np.ptp(1e-6 * u)
    )
    assert "largest on the descending branch" in left.sentence
    # And the ascending one, mirrored.
    mirrored = remainder(_recording(u), _noise(3) * np.where(falling, 1.0, 4.0))
    assert mirrored.branch == "ascending"


def test_a_quasi_static_record_names_the_cycle():
    k = np.arange(400)
    displacement = 0.01 * k * np.sin(2 * np.pi * k / 40)
    recording = jh.Recording.quasi_static(displacement, 3 * displacement)
    residual = 0.01 * np.random.default_rng(4).standard_normal(k.size)
    residual[250:270] += 0.5
    left = remainder(recording, residual)
    reversals = recording.reversals()
    half = int(np.searchsorted(reversals, 260, side="right")) + 1
    assert left.half_cycle == half and left.cycle == (half + 1) // 2
    assert left.half_cycles == reversals.size + 1
    assert left.span_first <= 250 and left.span_last >= 269
    assert left.sentence.startswith(
        f"The final model misses most in cycle {left.cycle} (half-cycle {half} of "
        f"{reversals.size + 1}, samples {left.span_first}-{left.span_last})"
    )
    assert " s " not in left.sentence  # no seconds on a pseudo time axis


def test_json_and_heldout(held_then_driven, tmp_path):
    residual = _noise(5)
    heldout = T > 20
    left = remainder(held_then_driven, residual, heldout=heldout)
    assert left.heldout_rms == pytest.approx(np.sqrt(np.mean(residual[heldout] ** 2)))
    data = json.loads(json.dumps(jsonable(left.to_dict()), allow_nan=False))
    assert data["verdict"] == "noise-like"
    assert data["span"]["event"] is None
    assert data["thresholds"]["lag1_noise_limit"] == LAG1_NOISE_LIMIT
    assert data["sentence"] == left.sentence


def test_bad_arguments_name_the_fix(held_then_driven):
    with pytest.raises(ValueError, match="recording.y - predicted"):
        remainder(held_then_driven, np.zeros(10))
    with pytest.raises(ValueError, match="NaN or inf"):
        remainder(held_then_driven, np.full(T.size, np.nan))
    with pytest.raises(ValueError, match="boolean mask"):
        remainder(held_then_driven, _noise(), heldout=np.ones(T.size))
