"""What is left: where the final model still misses most, on which branch of the
input, at which event, and whether the rest looks like noise.

`remainder(recording, residual)` reads the final residual y - yhat and returns a
`Remainder`, whose `sentence` says it in one line built only from the numbers it
cites.
"""

import math
from typing import Any

import equinox as eqx
import numpy as np

from .._recording import Recording
from ._locate import effective_samples


# The residual counts as noise-like when its lag-1 autocorrelation is below this...
LAG1_NOISE_LIMIT = 0.5
# ... and no span's RMS exceeds this many times the overall RMS.
SPAN_NOISE_LIMIT = 3.0
# An event (switch-on, start) is named only for a span at least this many times
# the overall RMS: a span that does not stand out is not an event.
EVENT_RATIO = 2.0
# Sliding spans cover this fraction of the record, and slide by a quarter of it.
SPAN_FRACTION = 1 / 20
# The input has started once it has moved by this fraction of its range.
MOVE_TOLERANCE = 0.01
# A branch (ascending / descending / holding) is ranked only when it holds at least
# this fraction of the samples.
MIN_BRANCH_FRACTION = 0.02
# The input holds where |du/dt| is below this fraction of its largest |du/dt|.
HOLD_TOLERANCE = 1e-3

# Events: the worst span holds the drive's start from rest ...
SWITCH_ON = "switch-on"
# ... or the first sample of a record that begins with the input already moving
# (at least START_RATE of its peak rate), e.g. a window cut from a longer test.
START = "start"
START_RATE = 0.05
# The input's rate at the start is the slope of a line through this many samples.
START_SAMPLES = 5


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else math.nan


def _ratio(a: float, b: float) -> float:
    return a / b if b > 0 else math.nan


def _fmt(value: float, digits: int = 4) -> str:
    return "n/a" if not math.isfinite(value) else f"{value:.{digits}g}"


def _percent(value: float) -> str:
    return "n/a" if not math.isfinite(value) else f"{100 * value:.1f} %"


class Remainder(eqx.Module):
    """Where the final model still misses most (`remainder`'s result).

    Amounts are in the recording's output unit, times in its time unit; spans
    are inclusive sample ranges [`span_first`, `span_last`]. `half_cycle` and
    `cycle` (1-based, counted from `Recording.reversals`) are set for quasi-static
    records, where they name the span instead of its time.
    """

    samples: int
    rms: float
    output_range: float
    span_first: int
    span_last: int
    span_start: float
    span_end: float
    span_rms: float
    span_max: float
    # The span's share of the total squared error.
    span_share: float
    branch: str
    branch_rms: float
    event: str | None
    # |du/dt| at the first sample over its peak over the record.
    start_rate: float
    half_cycle: int | None
    half_cycles: int | None
    cycle: int | None
    lag1_autocorrelation: float
    effective_samples: float
    heldout_rms: float | None
    time_unit: str
    output_unit: str
    pseudo_time: bool

    @property
    def span_ratio(self) -> float:
        """The worst span's RMS over the overall RMS."""
        return _ratio(self.span_rms, self.rms)

    @property
    def span_percent(self) -> float:
        """The worst span's RMS in percent of the output's range (max - min)."""
        return 100 * _ratio(self.span_rms, self.output_range)

    @property
    def branch_percent(self) -> float:
        """The worst branch's RMS in percent of the output's range."""
        return 100 * _ratio(self.branch_rms, self.output_range)

    @property
    def effective_fraction(self) -> float:
        """Effective independent samples over samples (1 for white noise)."""
        return _ratio(self.effective_samples, self.samples)

    @property
    def noise_like(self) -> bool:
        """Lag-1 autocorrelation below `LAG1_NOISE_LIMIT` and no span above
        `SPAN_NOISE_LIMIT` times the overall RMS."""
        return (
            self.lag1_autocorrelation < LAG1_NOISE_LIMIT
            and not self.span_ratio > SPAN_NOISE_LIMIT
        )

    @property
    def verdict(self) -> str:
        """ "noise-like" or "structured" (see `noise_like`)."""
        return "noise-like" if self.noise_like else "structured"

    @property
    def sentence(self) -> str:
        """`text()` in the recording's own units."""
        return self.text()

    def span_text(self) -> str:
        """The worst span in words: its times, or for quasi-static records its
        cycle and samples."""
        if self.pseudo_time:
            samples = f"samples {self.span_first}-{self.span_last}"
            if self.half_cycle is not None and self.half_cycles is not None:
                return (
                    f"cycle {self.cycle} (half-cycle {self.half_cycle} of "
                    f"{self.half_cycles}, {samples})"
                )
            if self.cycle is not None:
                return f"{samples} (cycle {self.cycle})"
            return samples
        unit = f" {self.time_unit}" if self.time_unit else ""
        return f"{self.span_start:.4g}-{self.span_end:.4g}{unit}"

    def text(self, scale: float = 1.0, unit: str | None = None) -> str:
        """One plain sentence; amounts shown times `scale` in `unit` (default: the
        output unit, scale 1), e.g. `text(1e6, "µm")` for a record in metres."""
        unit = self.output_unit if unit is None else unit
        s = f" {unit}" if unit else ""
        if not self.rms > 0:
            return "Nothing is left: the final model reproduces the record exactly."
        event = ""
        if self.event == SWITCH_ON:
            event = " (the switch-on transient)"
        elif self.event == START:
            event = (
                " (the start of the record, which begins mid-motion: the input "
                f"moves at {_fmt(100 * self.start_rate, 2)} % of its peak rate there)"
            )
        branch = (
            f"by branch of the input it is largest on the {self.branch} branch (RMS "
            f"{_fmt(scale * self.branch_rms)}{s}, "
            f"{_ratio(self.branch_rms, self.rms):.2f}x the overall RMS, "
            f"{_fmt(self.branch_percent, 3)} % of the range)"
        )
        lag1 = f"lag-1 autocorrelation {_fmt(self.lag1_autocorrelation, 3)}"
        if self.noise_like:
            return (
                f"What is left looks like noise: RMS {_fmt(scale * self.rms)}{s} "
                f"({_fmt(100 * _ratio(self.rms, self.output_range), 3)} % of the "
                f"output range), {lag1} (below {LAG1_NOISE_LIMIT:g}) and no span "
                f"above {SPAN_NOISE_LIMIT:g}x the overall RMS (the largest, "
                f"{self.span_text()}{event}, is {self.span_ratio:.1f}x); {branch}."
            )
        reasons = []
        if not self.lag1_autocorrelation < LAG1_NOISE_LIMIT:
            reasons.append(f"{lag1}, noise stays below {LAG1_NOISE_LIMIT:g}")
        if self.span_ratio > SPAN_NOISE_LIMIT:
            reasons.append(
                f"that span is {self.span_ratio:.1f}x the overall RMS, noise stays "
                f"below {SPAN_NOISE_LIMIT:g}x"
            )
        return (
            f"The final model misses most in {self.span_text()}{event}: RMS "
            f"{_fmt(scale * self.span_rms)}{s} ({_fmt(self.span_percent, 3)} % of "
            f"the output range, {self.span_ratio:.1f}x the overall RMS), "
            f"{_percent(self.span_share)} of the squared error; {branch}; the "
            f"residual is structured, not noise ({'; '.join(reasons)})."
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "sentence": self.sentence,
            "verdict": self.verdict,
            "rms": self.rms,
            "output_range": self.output_range,
            "span": {
                "first_sample": self.span_first,
                "last_sample": self.span_last,
                "start": self.span_start,
                "end": self.span_end,
                "rms": self.span_rms,
                "max_abs": self.span_max,
                "percent_of_range": self.span_percent,
                "ratio_to_overall_rms": self.span_ratio,
                "share_of_squared_error": self.span_share,
                "event": self.event,
                "start_rate": self.start_rate,
                "half_cycle": self.half_cycle,
                "cycle": self.cycle,
            },
            "branch": {
                "name": self.branch,
                "rms": self.branch_rms,
                "percent_of_range": self.branch_percent,
            },
            "lag1_autocorrelation": self.lag1_autocorrelation,
            "effective_samples": self.effective_samples,
            "effective_fraction": self.effective_fraction,
            "heldout_rms": self.heldout_rms,
            "time_unit": self.time_unit,
            "thresholds": {
                "lag1_noise_limit": LAG1_NOISE_LIMIT,
                "span_noise_limit": SPAN_NOISE_LIMIT,
                "event_ratio": EVENT_RATIO,
                "start_rate": START_RATE,
            },
        }


def _sliding_spans(n: int, anchors: tuple[int, ...]) -> list[tuple[int, int]]:
    """Inclusive windows of about `SPAN_FRACTION` of `n` samples, sliding by a
    quarter of that, plus windows starting at each of `anchors`."""
    length = min(n, max(5, round(n * SPAN_FRACTION)))
    step = max(1, length // 4)
    starts = set(range(0, n - length + 1, step)) | {n - length}
    starts |= {min(a, n - length) for a in anchors}
    return [(s, s + length - 1) for s in sorted(starts)]


def _half_cycle_spans(reversals: np.ndarray, n: int) -> list[tuple[int, int]]:
    bounds = [0, *(int(r) for r in reversals), n - 1]
    return [(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


def remainder(
    recording: Recording,
    residual: np.ndarray,
    *,
    heldout: np.ndarray | None = None,
) -> Remainder:
    """Where `residual` (y - yhat of the final model on `recording`) is largest.

    - The worst span: the sliding window of 1/20 of the record with the largest
      RMS (quasi-static records with two or more reversals: the worst half-cycle,
      named by its cycle), its RMS, max |residual| and share of the squared error.
    - The worst branch of the input (ascending / descending / holding, by the sign
      of du/dt) by RMS.
    - The event, when the worst span stands out (`EVENT_RATIO` times the overall
      RMS): "switch-on" when it holds the drive's start from rest (from the end of
      any initial hold to the input's first move by 1 % of its range); "start"
      when it holds the first sample of a record that begins mid-motion (the
      input's rate there at least `START_RATE` of its peak: a window cut from a
      longer test, where the model starts from a state the record does not show).
    - Whether the rest is noise-like: lag-1 autocorrelation and effective samples
      (see `Remainder.noise_like` for the thresholds).

    `heldout` (boolean mask, optional) adds the RMS on those samples.
    """
    residual = np.asarray(residual, dtype=np.float64)
    n = recording.num_samples
    if residual.shape != (n,):
        raise ValueError(
            f"remainder: residual has shape {residual.shape} but the recording "
            f"{recording.name!r} has {n} samples; pass recording.y - predicted."
        )
    if not np.all(np.isfinite(residual)):
        raise ValueError(
            "remainder: residual holds NaN or inf; pass the residual of a model "
            "whose output is finite."
        )
    heldout_rms = None
    if heldout is not None:
        mask = np.asarray(heldout)
        if mask.shape != (n,) or mask.dtype != np.bool_:
            raise ValueError(
                f"remainder: heldout must be a boolean mask of {n} samples, got "
                f"dtype {mask.dtype} and shape {mask.shape}; pass e.g. "
                "diagnosis.heldout, or None."
            )
        heldout_rms = _rms(residual[mask]) if mask.any() else None

    y, u = np.asarray(recording.y), np.asarray(recording.u)
    squared = residual**2
    total = float(np.sum(squared))
    rms = math.sqrt(total / n)
    udot = np.gradient(u, recording.dt)
    speed = np.abs(udot)
    moving = speed > HOLD_TOLERANCE * float(np.max(speed))
    # The drive's start: the input's first move by MOVE_TOLERANCE of its range,
    # traced back to the end of any initial hold.
    moved = np.flatnonzero(np.abs(u - u[0]) > MOVE_TOLERANCE * float(np.ptp(u)))
    first_move = int(moved[0]) if moved.size else 0
    held = np.flatnonzero(~moving[:first_move])
    drive_start = int(held[-1]) + 1 if held.size else 0

    reversals = recording.reversals() if recording.has_pseudo_time else None
    if reversals is not None and reversals.size >= 2:
        spans = _half_cycle_spans(reversals, n)
    else:
        spans = _sliding_spans(n, (drive_start,))
    cumulative = np.concatenate([[0.0], np.cumsum(squared)])
    energies = np.array([cumulative[b + 1] - cumulative[a] for a, b in spans])
    lengths = np.array([b - a + 1 for a, b in spans])
    worst = int(np.argmax(energies / lengths))
    first, last = spans[worst]
    span_rms = math.sqrt(energies[worst] / lengths[worst])
    span_max = float(np.max(np.abs(residual[first : last + 1])))

    half_cycle = half_cycles = cycle = None
    if reversals is not None:
        # Half-cycle k (1-based) runs from reversal k-1 (or the start) to reversal k.
        middle = (first + last) // 2
        half = int(np.searchsorted(reversals, middle, side="right")) + 1
        cycle = (half + 1) // 2
        if reversals.size >= 2:  # the spans are the half-cycles
            half_cycle, half_cycles = half, int(reversals.size) + 1

    event = None
    # The input's rate at the start: a line through the first few samples.
    head = slice(0, min(n, START_SAMPLES))
    slope = np.polyfit(np.asarray(recording.t[head]), u[head], 1)[0]
    start_rate = _ratio(abs(float(slope)), float(np.max(speed)))
    if _ratio(span_rms, rms) >= EVENT_RATIO:
        if start_rate >= START_RATE and first == 0:
            event = START
        elif first <= first_move and last >= drive_start:
            event = SWITCH_ON

    branches = {
        "ascending": moving & (udot > 0),
        "descending": moving & (udot < 0),
        "holding": ~moving,
    }
    ranked = {
        name: _rms(residual[mask])
        for name, mask in branches.items()
        if mask.mean() >= MIN_BRANCH_FRACTION
    }
    branch = max(ranked, key=lambda name: ranked[name])

    centred = residual - residual.mean()
    lag1 = float(
        np.dot(centred[:-1], centred[1:]) / max(np.dot(centred, centred), 1e-300)
    )
    return Remainder(
        samples=n,
        rms=rms,
        output_range=float(np.ptp(y)),
        span_first=first,
        span_last=last,
        span_start=float(recording.t[first]),
        span_end=float(recording.t[last]),
        span_rms=span_rms,
        span_max=span_max,
        span_share=_ratio(float(energies[worst]), total),
        branch=branch,
        branch_rms=ranked[branch],
        event=event,
        start_rate=start_rate,
        half_cycle=half_cycle,
        half_cycles=half_cycles,
        cycle=cycle,
        lag1_autocorrelation=lag1,
        effective_samples=float(effective_samples(residual)),
        heldout_rms=heldout_rms,
        time_unit=recording.time_unit,
        output_unit=recording.output_unit,
        pseudo_time=recording.has_pseudo_time,
    )
