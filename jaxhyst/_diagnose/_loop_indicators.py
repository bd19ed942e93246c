"""Model-free loop indicators of a quasi-static cyclic test: whether its loops
degrade and pinch, read from the loops themselves, and whether a diagnosis's named
effects agree with them.

`loop_indicators(recording)` splits a record (u the displacement, y the force) into
half cycles at the displacement's reversals (ignoring reversals smaller than
`REVERSAL_SHARE` of the peak displacement, so noise makes none), pairs them into
cycles (a push and a pull, in the order the test applies them) and groups
consecutive cycles that reach about the same displacements (`LEVEL_TOLERANCE`) into
amplitude levels. Per cycle it measures, without any model:

- the force at its peak displacements (a line through the branch's samples within
  `WINDOW` of the peak, so that one noisy sample does not set it), its
  peak-to-peak secant stiffness, and, on the later cycles of a level, the force at
  the same displacement as the level's first cycle (the smaller of the two peaks);
- the force at zero displacement (the cycle's centre) on both branches, as the
  loop's height there over its peak-to-peak force: 1 for a rectangular
  (elastic-perfectly-plastic) loop, near 0 for a pinched (or an elastic) one;
- the energy it dissipates (the trapezoid integral of F dx around the closed
  loop) over that of the elastic-perfectly-plastic cycle with the same peak forces
  and displacements, (F+ - F-)(x+ - x-) (4 Fmax xmax for a symmetric cycle;
  Jacobsen's equivalent viscous damping of a symmetric cycle is 2/pi times it);
- how steeply it unloads from its peaks, over its secant stiffness (a pinched
  loop unloads steeply, then slips; a nearly elastic one unloads along its
  secant).

Cycles that are not whole loops (their first half starts well inside them, as in
an irregular history) give no loop shape; a record whose force scatters by more
than `NOISE_SHARE` of its peak from sample to sample, or whose force does not rise
with the displacement, gives no verdict. From these numbers it answers two
questions, each "yes", "no" or "cannot tell" with a one-line reason
(`LoopVerdict`): do the loops degrade (strength at equal displacement over the
repeated cycles, and the envelope's loss past its peak), and do they pinch (the
force at zero displacement, the energy ratio and the unloading at the largest
amplitudes). The thresholds, and what each rests on, are the constants below.
`compare_loops(effects, indicators, ...)` sets these beside the effects a diagnosis
named. Everything here is NumPy; nothing is fitted.
"""

import dataclasses
import math
from collections.abc import Iterable, Mapping
from typing import Any

import equinox as eqx
import numpy as np

from .._recording import Recording


# Reversals whose excursion is smaller than this share of the peak |displacement|
# are ignored (`Recording.reversals`' tolerance): displacement noise and actuator
# wiggles are well below it, the first levels of a FEMA 461 (2007) ladder
# (amplitudes growing 1.4 times a step, about ten steps) are above it.
REVERSAL_SHARE = 0.02
# Consecutive cycles whose push and pull peaks are each within this share of the
# level's first cycle's amplitude are cycles of one amplitude level. Test
# controllers repeat a level's peaks to a few per cent (kunnath's second level
# reaches 14.4 then 15.5 mm); an earthquake-like history rarely repeats two
# cycles this closely.
LEVEL_TOLERANCE = 0.10
# A cycle is a whole loop if its first half cycle covers at least this share of its
# displacement range: the first cycle of a ladder's level starts from the smaller
# level before it (about 85 % for FEMA 461's steps of 1.4, 69 % for the CUREE
# primary cycles of timber_steel_plate); an irregular history's cycle may start
# near its middle.
WHOLE = 0.6
# The force at a displacement is read off a line through the branch's samples
# within this share of the cycle's amplitude of it (at least the two samples around
# it), which averages the load cell's noise over the samples there.
WINDOW = 0.10
# The levels the pinching verdict reads: those reaching at least this share of the
# test's largest amplitude (past yield in any test that reaches a few times the
# yield displacement, as FEMA 461's and ATC-24's ladders do).
UPPER_SHARE = 0.5

# Degradation. Cyclic loss: the median, over the levels with repeated cycles and
# both directions, of the second cycle's loss of force at the first cycle's
# displacement (FEMA P-440A (2009) calls this cyclic strength degradation). No
# standard sets a threshold for it, so 10 % is a judgement between two marks:
# ACI 374.1-05 accepts a frame module whose third cycle at 3.5 % drift keeps 75 %
# of its peak strength (25 % lost), Park (1989) takes a 20 % loss as failure, and
# members that do not degrade repeat a level's force to within a few per cent (the
# RC tests of jh.datasets lose 1-4 %). Below `CYCLIC_NONE` the loops do not degrade
# cyclically; between the two the loss is slight, and said so.
CYCLIC_LOSS = 0.10
CYCLIC_NONE = 0.05
# Envelope (post-peak) loss: 1 - the force at the test's largest displacement over
# the test's peak force, per direction. 20 % is Park's (1989, Bull. NZSEE 22(3))
# definition of the available (ultimate) displacement: where the load capacity has
# fallen to 80 % of its maximum, the member has failed.
ENVELOPE_LOSS = 0.20
# Too noisy to read loops: the force's sample-to-sample scatter (a robust estimate
# from its second differences) above this share of the peak force. The real tests
# of jh.datasets scatter by at most 0.6 %; at 5 % a level's ratios move by several
# per cent, as much as the thresholds below tell apart.
NOISE_SHARE = 0.05
# Too few repeated cycles to read a cyclic loss: fewer levels with two or more
# cycles than this.
MIN_REPEATED_LEVELS = 2

# Pinching, read at the upper levels (medians over their cycles) from two ratios
# that are 1 for the elastic-perfectly-plastic rectangle: the loop's height at zero
# displacement over its peak-to-peak force, and its energy over the rectangle's,
# (F+ - F-)(x+ - x-) (Jacobsen's equivalent viscous damping of a symmetric cycle is
# 2/pi times it). ACI 374.1-05 accepts a frame module only if its relative energy
# dissipation ratio (on a smaller, parallelogram reference) is at least 1/8, against
# severe pinching, and its commentary reports about 0.3 as typical of RC modules.
# Calibrated on this package's loops: both below 0.30 on the pinched RC and timber
# tests of jh.datasets (0.04-0.27) and on Baber-Noori and slip-lock loops; both at
# or above 0.45 and 0.35 on unpinched Bouc-Wen loops past yield (0.5-0.85 and
# 0.35-0.6 on jh.synthetic's clean structural cases). Between the two a loop is
# thinner than a full one without being pinched for certain: stiffness-degrading
# (Takeda-like) RC loops sit there.
ZERO_FORCE_PINCHED = 0.30
ENERGY_PINCHED = 0.30
ZERO_FORCE_FULL = 0.45
ENERGY_FULL = 0.35
# The loops at the upper levels must be past yield for either ratio to mean
# pinching (an elastic loop has neither force at zero displacement nor area): their
# secant stiffness below this share of the first cycle's.
YIELDED_STIFFNESS = 0.7
# A thin loop is pinched only if it unloads steeply from its peaks (then slips):
# its unloading stiffness (over the first `UNLOAD_SHARE` of the peak-to-peak force
# after a reversal) at least `UNLOADING_PINCHED` times its peak-to-peak secant. A
# nearly elastic loop (a rocking, self-centring wall, a member softened to a thin
# lens, or one barely past yield) unloads along its secant, about 1 times it.
UNLOAD_SHARE = 0.25
UNLOADING_PINCHED = 2.0

ANSWERS = ("yes", "no", "cannot tell")


class LoopVerdict(eqx.Module):
    """One model-free answer: `answer` is "yes", "no" or "cannot tell", `reason`
    says why in one line, `measure` is the number it rests on (NaN: none)."""

    answer: str
    reason: str
    measure: float = math.nan

    def __check_init__(self):
        if self.answer not in ANSWERS:
            raise ValueError(
                f"LoopVerdict: answer must be one of {ANSWERS}, got {self.answer!r}."
            )

    def to_dict(self) -> dict[str, Any]:
        return {"answer": self.answer, "reason": self.reason, "measure": self.measure}


class LoopCycle(eqx.Module):
    """One cycle: a push and a pull half cycle (in the order the test applies
    them), samples `start` to `end` (inclusive), in amplitude level `level`.

    `peak_displacement` and `peak_force` are (push, pull), the pull's negative;
    `stiffness` the peak-to-peak secant (F+ - F-)/(x+ - x-); `energy` the
    integral of F dx over the cycle and `energy_ratio` it over (F+ - F-)(x+ - x-);
    `zero_force_ratio` the loop's height at zero displacement (the cycle's centre)
    over F+ - F-; `unloading_ratio` its unloading stiffness from the peaks (over
    the first quarter of F+ - F-) over the secant (the energy, these three ratios
    are NaN where the cycle is not a whole loop); `strength_ratio` (push, pull) the
    force at the level's first cycle's displacement over the first cycle's (1 on
    the first cycle of a level)."""

    start: int
    end: int
    level: int
    peak_displacement: tuple[float, float]
    peak_force: tuple[float, float]
    stiffness: float
    energy: float
    energy_ratio: float
    zero_force_ratio: float
    unloading_ratio: float
    strength_ratio: tuple[float, float]

    @property
    def amplitude(self) -> float:
        """Half the peak-to-peak displacement."""
        return 0.5 * (self.peak_displacement[0] - self.peak_displacement[1])

    def to_dict(self) -> dict[str, Any]:
        return {
            "start": self.start,
            "end": self.end,
            "level": self.level,
            "peak_displacement": list(self.peak_displacement),
            "peak_force": list(self.peak_force),
            "stiffness": self.stiffness,
            "energy": self.energy,
            "energy_ratio": self.energy_ratio,
            "zero_force_ratio": self.zero_force_ratio,
            "unloading_ratio": self.unloading_ratio,
            "strength_ratio": list(self.strength_ratio),
        }


class LoopLevel(eqx.Module):
    """Consecutive cycles at about the same displacements.

    `amplitude` and `peak_force` are the first cycle's half peak-to-peak
    displacement and force, `stiffness` its secant; `second_strength_ratio` the
    second cycle's force at the first's displacement over the first's (mean of push
    and pull; NaN for a level of one cycle), `last_strength_ratio` the same for the
    last cycle, `stiffness_ratio` the second cycle's secant over the first's;
    `zero_force_ratio`, `energy_ratio` and `unloading_ratio` the medians over the
    level's cycles."""

    first_cycle: int
    cycles: int
    amplitude: float
    peak_force: float
    stiffness: float
    second_strength_ratio: float
    last_strength_ratio: float
    stiffness_ratio: float
    zero_force_ratio: float
    energy_ratio: float
    unloading_ratio: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "first_cycle": self.first_cycle,
            "cycles": self.cycles,
            "amplitude": self.amplitude,
            "peak_force": self.peak_force,
            "stiffness": self.stiffness,
            "second_strength_ratio": self.second_strength_ratio,
            "last_strength_ratio": self.last_strength_ratio,
            "stiffness_ratio": self.stiffness_ratio,
            "zero_force_ratio": self.zero_force_ratio,
            "energy_ratio": self.energy_ratio,
            "unloading_ratio": self.unloading_ratio,
        }


class LoopIndicators(eqx.Module):
    """What a cyclic test's loops show without a model (`loop_indicators`).

    `cycles` and `levels` hold the per-cycle and per-level numbers; the summaries:
    `strength_loss` the median loss of force at equal displacement of a level's
    second cycle against its first (over `repeated_levels` levels and both
    directions; NaN without repeats), `last_strength_loss` the same for the last
    cycle, `stiffness_loss` the median loss of secant stiffness of the second cycle;
    `envelope_loss` (push, pull) 1 - the force at the largest displacement over the
    test's peak force in that direction; `zero_force_ratio`, `energy_ratio` and
    `unloading_ratio` the medians over the cycles reaching `UPPER_SHARE` of the
    largest amplitude; `degradation` and `pinching` the verdicts."""

    recording: str
    reversals: int
    cycles: tuple[LoopCycle, ...]
    levels: tuple[LoopLevel, ...]
    repeated_levels: int
    strength_loss: float
    last_strength_loss: float
    stiffness_loss: float
    envelope_loss: tuple[float, float]
    zero_force_ratio: float
    energy_ratio: float
    unloading_ratio: float
    degradation: LoopVerdict
    pinching: LoopVerdict

    @property
    def verdicts(self) -> dict[str, LoopVerdict]:
        """{"degradation": ..., "pinching": ...}."""
        return {"degradation": self.degradation, "pinching": self.pinching}

    def to_dict(self) -> dict[str, Any]:
        return {
            "recording": self.recording,
            "reversals": self.reversals,
            "degradation": self.degradation.to_dict(),
            "pinching": self.pinching.to_dict(),
            "repeated_levels": self.repeated_levels,
            "strength_loss": self.strength_loss,
            "last_strength_loss": self.last_strength_loss,
            "stiffness_loss": self.stiffness_loss,
            "envelope_loss": list(self.envelope_loss),
            "zero_force_ratio": self.zero_force_ratio,
            "energy_ratio": self.energy_ratio,
            "unloading_ratio": self.unloading_ratio,
            "levels": [level.to_dict() for level in self.levels],
            "cycles": [cycle.to_dict() for cycle in self.cycles],
            "thresholds": {
                "reversal_share": REVERSAL_SHARE,
                "noise_share": NOISE_SHARE,
                "level_tolerance": LEVEL_TOLERANCE,
                "cyclic_loss": CYCLIC_LOSS,
                "cyclic_none": CYCLIC_NONE,
                "envelope_loss": ENVELOPE_LOSS,
                "upper_share": UPPER_SHARE,
                "zero_force_pinched": ZERO_FORCE_PINCHED,
                "energy_pinched": ENERGY_PINCHED,
                "zero_force_full": ZERO_FORCE_FULL,
                "energy_full": ENERGY_FULL,
                "yielded_stiffness": YIELDED_STIFFNESS,
                "unloading_pinched": UNLOADING_PINCHED,
            },
        }


class LoopAgreement(eqx.Module):
    """Whether a named effect and the loops agree: `effect` ("degradation" or
    "pinching"), `named` (whether the diagnosis named it), `loops` the loops'
    answer ("yes", "no", "cannot tell"), `agree` True, False, or None where the
    loops cannot tell, and `statement` in words (with why, where they disagree)."""

    effect: str
    named: bool
    loops: str
    agree: bool | None
    statement: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "effect": self.effect,
            "named": self.named,
            "loops": self.loops,
            "agree": self.agree,
            "statement": self.statement,
        }


# ------------------------------------------------------------------ measurement


def _force_at(x: np.ndarray, f: np.ndarray, target: float, window: float) -> float:
    """The force of a branch (x rising towards its end) at displacement `target`:
    a least-squares line through its samples within `window` of it (three or more,
    spread over half the window), else the two samples around its last crossing;
    NaN where the branch does not come within `window` of it."""
    if x.size == 0 or target > np.max(x) + window or target < np.min(x) - window:
        return math.nan
    near = np.abs(x - target) <= window
    if np.count_nonzero(near) >= 3 and np.ptp(x[near]) > 0.5 * window:
        slope, intercept = np.polyfit(x[near], f[near], 1)
        return float(slope * target + intercept)
    below = np.flatnonzero(x <= target)
    if below.size == 0:
        return float(f[0])
    k = int(below[-1])
    if k == x.size - 1:
        return float(f[k])
    span = x[k + 1] - x[k]
    share = (target - x[k]) / span if span > 0 else 0.0
    return float(f[k] + share * (f[k + 1] - f[k]))


def _unloading(half: "_Half", drop: float) -> float:
    """The displacement a half cycle travels from its start (a reversal) until its
    force has changed by `drop` (interpolated; NaN if it never does)."""
    change = half.f - half.f[0]
    past = np.flatnonzero(change >= drop)
    if past.size == 0 or drop <= 0:
        return math.nan
    k = int(past[0])
    if k == 0:
        return 0.0
    share = (drop - change[k - 1]) / (change[k] - change[k - 1])
    return float(half.x[k - 1] - half.x[0] + share * (half.x[k] - half.x[k - 1]))


def _loop_work(x: np.ndarray, f: np.ndarray) -> float:
    """The trapezoid integral of F dx along the samples and back to the first (the
    area of the closed loop; positive for a loop run clockwise, as hysteresis
    is)."""
    xs, fs = np.append(x, x[0]), np.append(f, f[0])
    return float(np.sum(0.5 * (fs[1:] + fs[:-1]) * np.diff(xs)))


class _Half(eqx.Module):
    """One half cycle, samples `start`..`end`, oriented so that it rises (x and F
    times `sign`)."""

    start: int
    end: int
    sign: float
    x: np.ndarray
    f: np.ndarray

    @property
    def peak(self) -> float:
        return float(self.x[-1])


def _halves(x: np.ndarray, f: np.ndarray, reversals: np.ndarray) -> list[_Half]:
    ends = [int(r) for r in reversals]
    starts = [0, *ends[:-1]]
    out = []
    for start, end in zip(starts, ends, strict=True):
        sign = 1.0 if x[end] >= x[start] else -1.0
        xs, fs = sign * x[start : end + 1], sign * f[start : end + 1]
        out.append(_Half(start, end, sign, xs, fs))
    return out


def _scatter(f: np.ndarray) -> float:
    """The force's sample-to-sample noise: a robust standard deviation of its
    second differences (which a smooth loop barely has), over sqrt(6) (white
    noise's second differences have 6 times its variance)."""
    if f.size < 3:
        return 0.0
    second = np.diff(f, 2)
    spread = np.median(np.abs(second - np.median(second)))
    return float(1.4826 * spread / math.sqrt(6))


def _ratio(a: float, b: float) -> float:
    """a / b, NaN where b is zero or not finite."""
    return a / b if b != 0 and math.isfinite(b) else math.nan


def _median(values: Iterable[float]) -> float:
    kept = [v for v in values if not math.isnan(v)]
    return float(np.median(kept)) if kept else math.nan


def _phase(halves: list[_Half]) -> int:
    """Which half cycle the cycles start with (0 or 1): the pairing whose push and
    pull peaks match best (a ladder's cycle is its level's push and pull, not one
    level's pull and the next one's push; a first excursion too small to count as
    a reversal must not shift the pairing)."""

    def match(phase: int) -> float:
        pairs = list(zip(halves[phase::2], halves[phase + 1 :: 2]))
        if not pairs:
            return -1.0
        ratios = [
            min(a.peak, b.peak) / max(a.peak, b.peak)
            if min(a.peak, b.peak) > 0
            else 0.0
            for a, b in pairs
        ]
        return float(np.mean(ratios))

    return 1 if match(1) > match(0) else 0


@dataclasses.dataclass
class _Cycle:
    """One cycle as `_cycles` reads it: its push and pull halves, their peak
    displacements (`x`) and forces (`f`), and the loop's numbers (`LoopCycle`'s);
    `level` and `strength_ratio` are set once the levels are known."""

    start: int
    end: int
    push: "_Half"
    pull: "_Half"
    x: tuple[float, float]
    f: tuple[float, float]
    amplitude: float
    window: float
    stiffness: float
    energy: float
    energy_ratio: float
    zero_force_ratio: float
    unloading_ratio: float
    level: int = -1
    strength_ratio: tuple[float, float] = (1.0, 1.0)


def _cycles(
    halves: list[_Half], x: np.ndarray, f: np.ndarray
) -> tuple[list[_Cycle], list[list[int]]]:
    """The cycles (push and pull half, as `_Cycle` records) and the levels
    (lists of cycle indices)."""
    cycles: list[_Cycle] = []
    phase = _phase(halves)
    for lead, back in zip(halves[phase::2], halves[phase + 1 :: 2]):
        push, pull = (lead, back) if lead.sign > 0 else (back, lead)
        x_hi, x_lo = push.peak, -pull.peak
        amplitude = 0.5 * (x_hi - x_lo)
        if amplitude <= 0:
            continue
        window = WINDOW * amplitude
        f_hi = _force_at(push.x, push.f, x_hi, window)
        f_lo = -_force_at(pull.x, pull.f, -x_lo, window)
        centre = 0.5 * (x_hi + x_lo)
        up = _force_at(push.x, push.f, centre, window)
        down = -_force_at(pull.x, pull.f, -centre, window)
        height = f_hi - f_lo
        # Unloading stiffness over the secant: the force's first `UNLOAD_SHARE` of
        # the peak-to-peak force after each reversal, over the displacement it takes.
        travel = [_unloading(h, UNLOAD_SHARE * height) for h in (push, pull)]
        secant = height / (x_hi - x_lo)
        unloading = _median(
            (UNLOAD_SHARE * height / (d * secant) if d > 0 else math.inf)
            if secant > 0
            else math.nan
            for d in travel
        )
        # The loop: from where the lead half enters the cycle's range (it may come
        # from a larger excursion) to the back half's peak, closed.
        outside = np.flatnonzero(lead.x <= -back.peak)
        entry = lead.start + (int(outside[-1]) if outside.size else 0)
        energy = _loop_work(x[entry : back.end + 1], f[entry : back.end + 1])
        # A cycle whose lead half starts well inside its range (an irregular
        # history's small reversal) is not a whole loop: no loop shape is read off
        # it.
        whole = lead.peak - float(lead.x[0]) >= WHOLE * (x_hi - x_lo) and height > 0
        if not whole:
            energy = up = down = unloading = math.nan
        cycles.append(
            _Cycle(
                start=lead.start,
                end=back.end,
                push=push,
                pull=pull,
                x=(x_hi, x_lo),
                f=(f_hi, f_lo),
                amplitude=amplitude,
                window=window,
                stiffness=height / (x_hi - x_lo),
                energy=energy,
                energy_ratio=energy / (height * (x_hi - x_lo)) if whole else math.nan,
                zero_force_ratio=(up - down) / height if whole else math.nan,
                unloading_ratio=unloading,
            )
        )
    levels: list[list[int]] = []
    for i, cycle in enumerate(cycles):
        if levels:
            first = cycles[levels[-1][0]]
            reach = LEVEL_TOLERANCE * first.amplitude
            if all(abs(a - b) <= reach for a, b in zip(cycle.x, first.x, strict=True)):
                levels[-1].append(i)
                continue
        levels.append([i])
    return cycles, levels


def _strength_ratios(cycles: list[_Cycle], level: list[int]) -> None:
    """Each cycle's force at the level's first cycle's displacement (the smaller
    of its and theirs, per direction) over the first's, stored as its
    `strength_ratio`."""
    first = cycles[level[0]]
    first.strength_ratio = (1.0, 1.0)
    for i in level[1:]:
        cycle = cycles[i]
        ratios = []
        for mine, reference in ((cycle.push, first.push), (cycle.pull, first.pull)):
            target = min(mine.peak, reference.peak)
            window = min(cycle.window, first.window)
            now = _force_at(mine.x, mine.f, target, window)
            then = _force_at(reference.x, reference.f, target, window)
            ratios.append(now / then if then > 0 else math.nan)
        cycle.strength_ratio = (ratios[0], ratios[1])


def _envelope_loss(halves: list[_Half], sign: float) -> float:
    """1 - the force at the largest displacement in direction `sign` over the
    largest force of that direction's half cycles at their peaks."""
    mine = [h for h in halves if h.sign == sign and h.peak > 0]
    if len(mine) < 2:
        return math.nan
    forces = []
    for h in mine:
        window = WINDOW * 0.5 * (h.peak - float(h.x[0]))
        forces.append(_force_at(h.x, h.f, h.peak, window))
    peak = max(forces)
    largest = forces[int(np.argmax([h.peak for h in mine]))]
    return 1.0 - largest / peak if peak > 0 else math.nan


# ------------------------------------------------------------------- verdicts


def _percent(value: float) -> str:
    return f"{100 * value:.0f} %"


def _less(loss: float) -> str:
    """A loss of force in words: "12 % less", "3 % more", "the same"."""
    if abs(loss) < 0.005:
        return "the same"
    return f"{_percent(abs(loss))} {'less' if loss > 0 else 'more'}"


def _degradation(
    strength_loss: float,
    last_loss: float,
    repeated: int,
    envelope: tuple[float, float],
) -> LoopVerdict:
    worst = max((e for e in envelope if math.isfinite(e)), default=math.nan)
    post_peak = math.isfinite(worst) and worst >= ENVELOPE_LOSS
    if not math.isfinite(worst):
        envelope_text = ""
    elif worst < 0.005:
        envelope_text = "the largest displacements carry the test's peak force"
    else:
        side = "push" if envelope[0] == worst else "pull"
        envelope_text = (
            f"the force at the largest {side} displacement is {_percent(worst)} "
            "below the test's peak force"
        )
    lost = (
        f"{envelope_text} (a post-peak loss of {_percent(ENVELOPE_LOSS)} or more: "
        "the member has failed)"
    )
    if repeated < MIN_REPEATED_LEVELS or not math.isfinite(strength_loss):
        why = (
            "no amplitude level repeats its cycle"
            if repeated == 0
            else f"only {repeated} amplitude level repeats its cycle"
        )
        if post_peak:
            return LoopVerdict(
                "yes", f"{lost}; {why}, so the cyclic loss cannot be read", worst
            )
        tail = f"; {envelope_text}" if envelope_text else ""
        return LoopVerdict(
            "cannot tell",
            f"{why}, so no two cycles reach the same displacement to compare "
            f"(this needs {MIN_REPEATED_LEVELS} levels of two or more cycles){tail}",
            worst,
        )
    than = "as" if _less(strength_loss) == "the same" else "than"
    cyclic = (
        f"the second cycle at each level reaches {_less(strength_loss)} force at "
        f"the same displacement {than} the first (median of {repeated} levels, "
        "both directions)"
    )
    if math.isfinite(last_loss) and abs(last_loss - strength_loss) >= 0.02:
        cyclic += f", the last {_less(last_loss)}"
    if strength_loss >= CYCLIC_LOSS:
        tail = f"; {envelope_text}" if post_peak else ""
        return LoopVerdict("yes", cyclic + tail, strength_loss)
    if post_peak:
        return LoopVerdict("yes", f"{lost}; {cyclic}", worst)
    tail = f"; {envelope_text}" if envelope_text else ""
    if strength_loss >= CYCLIC_NONE:
        return LoopVerdict(
            "no",
            f"only slightly: {cyclic}, under the {_percent(CYCLIC_LOSS)} of a "
            f"degrading member{tail}",
            strength_loss,
        )
    return LoopVerdict("no", cyclic + tail, strength_loss)


def _pinching(
    cycles: list[_Cycle],
    upper: list[int],
    zero: float,
    energy: float,
    unloading: float,
) -> LoopVerdict:
    if not upper:
        return LoopVerdict("cannot tell", "no complete cycle at the largest amplitudes")
    if not (math.isfinite(zero) and math.isfinite(energy)):
        return LoopVerdict(
            "cannot tell",
            "the cycles at the largest amplitudes are not whole loops (each starts "
            "from a reversal inside it, as an irregular history's do), so their "
            "force at zero displacement and their energy cannot be read",
        )
    first = cycles[0].stiffness
    secant = (
        _median(cycles[i].stiffness for i in upper) / first if first > 0 else math.nan
    )
    numbers = (
        f"at the largest amplitudes ({len(upper)} cycle"
        f"{'s' if len(upper) != 1 else ''} from {_percent(UPPER_SHARE)} of the "
        f"largest) the force at zero displacement is {_percent(zero)} of the peak "
        f"force and the loops dissipate {_percent(energy)} of the rectangle's energy"
    )
    if not (math.isfinite(secant) and secant <= YIELDED_STIFFNESS):
        return LoopVerdict(
            "cannot tell",
            f"the loops at the largest amplitudes keep {_percent(secant)} of the "
            "first cycle's secant stiffness: too little past yield to tell a "
            f"pinched loop from an elastic one ({numbers})",
            zero,
        )
    if zero < ZERO_FORCE_PINCHED and energy < ENERGY_PINCHED:
        if unloading >= UNLOADING_PINCHED:
            return LoopVerdict(
                "yes",
                f"{numbers}, and they unload {unloading:.1f} times as stiffly as "
                "their secant before they slip: pinched loops",
                zero,
            )
        return LoopVerdict(
            "cannot tell",
            f"{numbers}, but they unload only {unloading:.1f} times as stiffly as "
            "their secant: thin, nearly elastic loops (a self-centring, rocking or "
            "softened member, or one barely past yield), not a slip that opens and "
            "closes",
            zero,
        )
    if zero >= ZERO_FORCE_FULL and energy >= ENERGY_FULL:
        return LoopVerdict("no", f"{numbers}, as full (unpinched) loops do", zero)
    return LoopVerdict(
        "cannot tell",
        f"{numbers}: thinner than full loops (from {_percent(ZERO_FORCE_FULL)} and "
        f"{_percent(ENERGY_FULL)}), not as thin as pinched ones (below "
        f"{_percent(ZERO_FORCE_PINCHED)} and {_percent(ENERGY_PINCHED)}); "
        "stiffness-degrading loops look like this too",
        zero,
    )


def _no_cycles(name: str, reversals: int, reason: str) -> LoopIndicators:
    why = LoopVerdict("cannot tell", reason)
    nan = math.nan
    return LoopIndicators(
        recording=name,
        reversals=reversals,
        cycles=(),
        levels=(),
        repeated_levels=0,
        strength_loss=nan,
        last_strength_loss=nan,
        stiffness_loss=nan,
        envelope_loss=(nan, nan),
        zero_force_ratio=nan,
        energy_ratio=nan,
        unloading_ratio=nan,
        degradation=why,
        pinching=why,
    )


def loop_indicators(recording: Recording) -> LoopIndicators:
    """The model-free loop indicators of a quasi-static cyclic test (`recording`: u
    the displacement, y the force; see the module docstring for what is measured
    and the thresholds of the verdicts). A record without reversals, too noisy,
    whose force does not follow its displacement, without repeated cycles or not
    far enough past yield gets "cannot tell" with the reason, never an error;
    raises TypeError unless `recording` is a `Recording`."""
    if not isinstance(recording, Recording):
        raise TypeError(
            "loop_indicators: recording must be a jaxhyst Recording (u the "
            f"displacement, y the force), got {type(recording).__name__}."
        )
    x = np.asarray(recording.u, dtype=np.float64)
    f = np.asarray(recording.y, dtype=np.float64)
    span = float(np.ptp(x))
    peak = float(np.max(np.abs(x)))
    if not (span > 0 and np.ptp(f) > 0):
        return _no_cycles(
            recording.name, 0, "the force or the displacement does not vary"
        )
    tolerance = min(REVERSAL_SHARE * peak / span, 0.5)
    reversals = recording.reversals(tolerance=tolerance)
    if reversals.size < 2:
        return _no_cycles(
            recording.name,
            int(reversals.size),
            f"the displacement reverses {reversals.size} time"
            f"{'s' if reversals.size != 1 else ''} (beyond "
            f"{_percent(REVERSAL_SHARE)} of its peak): a monotonic or one-sided "
            "record has no complete cycle",
        )
    scatter = _scatter(f) / float(np.max(np.abs(f)))
    if scatter > NOISE_SHARE:
        return _no_cycles(
            recording.name,
            int(reversals.size),
            f"the force scatters by {_percent(scatter)} of its peak from one sample "
            f"to the next (more than {_percent(NOISE_SHARE)}): too noisy to read "
            "its loops",
        )
    halves = _halves(x, f, reversals)
    cycles, levels = _cycles(halves, x, f)
    if not cycles:
        return _no_cycles(
            recording.name, int(reversals.size), "no cycle spans both directions"
        )
    backwards = sum(1 for c in cycles if not c.f[0] > c.f[1])
    if 2 * backwards > len(cycles):
        return _no_cycles(
            recording.name,
            int(reversals.size),
            f"in {backwards} of {len(cycles)} cycles the force at the push peak is "
            "not above the force at the pull peak: the force does not follow the "
            "displacement as a restoring force does (check the columns and the "
            "force's sign)",
        )
    for index, level in enumerate(levels):
        for i in level:
            cycles[i].level = index
        _strength_ratios(cycles, level)

    level_records = []
    second_losses, last_losses, stiffness_losses = [], [], []
    for level in levels:
        first = cycles[level[0]]
        second = cycles[level[1]] if len(level) > 1 else None
        last = cycles[level[-1]] if len(level) > 1 else None
        second_ratio = float(np.mean(second.strength_ratio)) if second else math.nan
        last_ratio = float(np.mean(last.strength_ratio)) if last else math.nan
        stiffness_ratio = (
            _ratio(second.stiffness, first.stiffness) if second else math.nan
        )
        if second is not None and last is not None:
            second_losses += [1 - r for r in second.strength_ratio]
            last_losses += [1 - r for r in last.strength_ratio]
            stiffness_losses.append(1 - stiffness_ratio)
        level_records.append(
            LoopLevel(
                first_cycle=level[0],
                cycles=len(level),
                amplitude=first.amplitude,
                peak_force=0.5 * (first.f[0] - first.f[1]),
                stiffness=first.stiffness,
                second_strength_ratio=second_ratio,
                last_strength_ratio=last_ratio,
                stiffness_ratio=stiffness_ratio,
                zero_force_ratio=_median(cycles[i].zero_force_ratio for i in level),
                energy_ratio=_median(cycles[i].energy_ratio for i in level),
                unloading_ratio=_median(cycles[i].unloading_ratio for i in level),
            )
        )
    repeated = sum(1 for level in levels if len(level) > 1)
    strength_loss = _median(second_losses)
    last_loss = _median(last_losses)
    envelope = (_envelope_loss(halves, 1.0), _envelope_loss(halves, -1.0))
    largest = max(c.amplitude for c in cycles)
    upper = [i for i, c in enumerate(cycles) if c.amplitude >= UPPER_SHARE * largest]
    zero = _median(cycles[i].zero_force_ratio for i in upper)
    energy = _median(cycles[i].energy_ratio for i in upper)
    unloading = _median(cycles[i].unloading_ratio for i in upper)
    return LoopIndicators(
        recording=recording.name,
        reversals=int(reversals.size),
        cycles=tuple(
            LoopCycle(
                start=c.start,
                end=c.end,
                level=c.level,
                peak_displacement=c.x,
                peak_force=c.f,
                stiffness=c.stiffness,
                energy=c.energy,
                energy_ratio=c.energy_ratio,
                zero_force_ratio=c.zero_force_ratio,
                unloading_ratio=c.unloading_ratio,
                strength_ratio=c.strength_ratio,
            )
            for c in cycles
        ),
        levels=tuple(level_records),
        repeated_levels=repeated,
        strength_loss=strength_loss,
        last_strength_loss=last_loss,
        stiffness_loss=_median(stiffness_losses),
        envelope_loss=envelope,
        zero_force_ratio=zero,
        energy_ratio=energy,
        unloading_ratio=unloading,
        degradation=_degradation(strength_loss, last_loss, repeated, envelope),
        pinching=_pinching(cycles, upper, zero, energy, unloading),
    )


# ------------------------------------------------------------------ comparison


COMPARED = ("degradation", "pinching")
"""The effects whose names `compare_loops` sets beside the loops."""


def _in_short(effect: str, indicators: LoopIndicators) -> str:
    """The loops' numbers for `effect`, in a few words."""
    if effect == "degradation":
        parts = []
        if math.isfinite(indicators.strength_loss):
            parts.append(
                f"{_percent(indicators.strength_loss)} less force at equal "
                "displacement on a level's second cycle"
            )
        worst = max(
            (e for e in indicators.envelope_loss if math.isfinite(e)),
            default=math.nan,
        )
        if math.isfinite(worst):
            parts.append(
                f"the force at the largest displacement {_percent(worst)} below "
                "the test's peak"
            )
        return ", ".join(parts) or "no numbers"
    if not math.isfinite(indicators.zero_force_ratio):
        return "no numbers"
    return (
        f"force at zero displacement {_percent(indicators.zero_force_ratio)} of the "
        f"peak, energy {_percent(indicators.energy_ratio)} of the rectangle's"
    )


_WHAT = {
    "degradation": ("degrade", "do not degrade"),
    "pinching": ("pinch", "do not pinch"),
}


def compare_loops(
    effects: Iterable[str],
    indicators: LoopIndicators,
    *,
    undecided: Iterable[str] = (),
    not_named: Mapping[str, str] | None = None,
) -> tuple[LoopAgreement, ...]:
    """Whether the effects a diagnosis named (`effects`) agree with what the loops
    show without a model (`indicators`), for `COMPARED` (degradation, pinching).

    Where they disagree the statement says why, as far as the caller knows:
    `undecided` names the effects the diagnosis left undecided (its ambiguities),
    `not_named` says per effect why it was not named ("the held-out cycles did not
    support it"); a named effect the loops do not show is said to fit something
    else in the loops' shape. Where the loops cannot tell, `agree` is None."""
    if not isinstance(indicators, LoopIndicators):
        raise TypeError(
            "compare_loops: indicators must be a LoopIndicators (from "
            f"loop_indicators(recording)), got {type(indicators).__name__}."
        )
    named = set(effects)
    open_ = set(undecided)
    reasons = dict(not_named or {})
    out = []
    for effect in COMPARED:
        verdict = indicators.verdicts[effect]
        is_named = effect in named
        shows, lacks = _WHAT[effect]
        numbers = _in_short(effect, indicators)
        if verdict.answer == "cannot tell":
            agree = None
            statement = (
                f"{effect} {'named' if is_named else 'not named'}; the loops cannot "
                f"tell whether they {shows}: {verdict.reason}"
            )
        elif (verdict.answer == "yes") == is_named:
            agree = True
            statement = (
                f"{effect} {'named' if is_named else 'not named'}, and the loops "
                f"{shows if is_named else lacks}: {verdict.reason}"
            )
        elif verdict.answer == "yes":
            agree = False
            if effect in open_:
                why = "the diagnosis left it undecided (see the ambiguities)"
            else:
                why = reasons.get(effect, "the diagnosis did not name it")
            statement = (
                f"the loops {shows} ({numbers}) but {effect} was not named: {why}"
            )
        else:
            agree = False
            if effect == "degradation":
                other = (
                    "what the named degradation fits is not a loss of strength at "
                    "equal displacement (it may fit how the loops' shape changes "
                    "from level to level, which a plain Bouc-Wen loop cannot follow)"
                )
            else:
                other = (
                    "what the named pinching fits is not a loop pinched at zero "
                    "displacement (a slip away from it, say, or a loop shape the "
                    "base model misses)"
                )
            statement = (
                f"{effect} named, but the loops {lacks} ({verdict.reason}): {other}"
            )
        out.append(
            LoopAgreement(
                effect=effect,
                named=is_named,
                loops=verdict.answer,
                agree=agree,
                statement=statement,
            )
        )
    return tuple(out)
