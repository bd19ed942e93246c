"""Piezo drives: the rich excitation an identification experiment is designed
with, and the plain drives people record (`AbstractExcitation`)."""

import abc
import math

import equinox as eqx
import numpy as np
from jaxtyping import PRNGKeyArray

from .._inputs import InputPath
from .._signals import (
    AbstractSignal,
    Chirp,
    Concatenate,
    Constant,
    DecayingCosine,
    Multisine,
    RaisedCosine,
    StepHold,
    Triangle,
    sample,
)
from ._checks import _check_positive
from ._random import _loguniform, _rng
from ._truth import _FULL_SCALE


# ------------------------------------------------------------ the rich excitation


def _whole_periods(frequency: float, target: float, budget: float) -> int:
    """How many whole periods of `frequency` last about `target` within `budget`."""
    most = math.floor(budget * frequency + 1e-9)
    return min(max(1, round(target * frequency)), most)


def _segment(
    kind: str, rng: np.random.Generator, budget: float, top: float
) -> AbstractSignal | None:
    """One excitation segment of at most `budget` seconds, or None if none fits. Every
    segment starts and ends at rest at its own level, inside [0, top]."""
    if kind == "slow":  # slow raised cosines, 0.1-0.5 Hz, large swing
        f_min = max(0.1, 1.0 / budget)
        if f_min > 0.5:
            return None
        f = _loguniform(rng, f_min, 0.5)
        periods = _whole_periods(f, rng.uniform(1, 2.5) / f, budget)
        base = rng.uniform(0.0, 0.15) * top
        peak = rng.uniform(0.7, 1.0) * top
        return RaisedCosine((peak - base) / 2, f, duration=periods / f, offset=base)
    if kind == "fast":  # faster raised cosines, 2-10 Hz, small swing anywhere
        f = _loguniform(rng, 2.0, 10.0)
        if budget < 2.0 / f or budget < 0.5:
            return None
        periods = _whole_periods(f, rng.uniform(1.5, 4.0), budget)
        base = rng.uniform(0.0, 0.6) * top
        swing = min(rng.uniform(0.05, 0.4) * top, top - base)
        return RaisedCosine(swing / 2, f, duration=periods / f, offset=base)
    if kind == "decaying":  # a nested family of shrinking loops
        f = _loguniform(rng, 0.5, 2.0)
        if budget < 3.0 / f:
            return None
        periods = _whole_periods(f, rng.uniform(3.0, 6.0), budget)
        base = rng.uniform(0.0, 0.2) * top
        amplitude = min(rng.uniform(0.3, 0.45) * top, (top - base) / 2)
        decay = rng.uniform(0.3, 0.6) * periods / f
        return DecayingCosine(amplitude, f, decay, duration=periods / f, offset=base)
    if kind == "chirp":  # a linear sweep through the rates
        f0, f1 = rng.uniform(0.2, 0.5), rng.uniform(4.0, 12.0)
        # Whole cycles, (f0 + f1) T / 2 = k, so the sweep ends where it started.
        k = _whole_periods((f0 + f1) / 2, rng.uniform(4.0, 8.0), budget)
        duration = 2 * k / (f0 + f1)
        if duration > budget or duration < 1.0:
            return None
        base = rng.uniform(0.0, 0.3) * top
        swing = min(rng.uniform(0.2, 0.5) * top, top - base)
        return Chirp(f0, f1, swing / 2, duration=duration, offset=base)
    if kind == "triangle":  # constant-rate ramps, sharp turning points
        f_min = max(0.2, 1.0 / budget)
        if f_min > 2.0:
            return None
        f = _loguniform(rng, f_min, 2.0)
        periods = _whole_periods(f, rng.uniform(2.0, 5.0), budget)
        base = rng.uniform(0.0, 0.4) * top
        swing = min(rng.uniform(0.2, 0.6) * top, top - base)
        return Triangle(swing / 2, f, duration=periods / f, offset=base)
    if kind == "steps":  # step-and-hold plateaus (creep shows on holds)
        hold = rng.uniform(1.0, 3.0)
        ramp = rng.uniform(0.05, 0.3)
        count = int(rng.integers(3, 6))
        count = min(count, math.floor((budget + ramp) / (hold + ramp)))
        if count < 2:
            hold = min(hold, (budget - ramp) / 2)
            count = 2
            if hold < 0.5:
                return None
        levels = rng.uniform(0.05, 0.95, size=count) * top
        return StepHold(levels, hold_time=hold, ramp_time=ramp)
    raise AssertionError(kind)  # pragma: no cover


_SEGMENT_KINDS = ("slow", "fast", "fast", "decaying", "chirp", "triangle", "steps")


def _transition(start: float, end: float, top: float) -> RaisedCosine:
    """A smooth (zero-rate at both ends) move from `start` to `end`."""
    duration = float(np.clip(abs(end - start) / top, 0.2, 1.0))
    return RaisedCosine(
        (end - start) / 2, 0.5 / duration, duration=duration, offset=start
    )


def _rich_signal(
    rng: np.random.Generator, duration: float, amplitude: float
) -> AbstractSignal:
    """Rest at 0, then every kind of segment once (in random order, each within its
    share of the time, so that short records still mix rates), then further random
    segments while they fit, then a move down and a final hold."""
    top = amplitude
    parts: list[AbstractSignal] = [Constant(0.0, duration=min(0.5, 0.05 * duration))]
    level, used = 0.0, parts[0].duration
    reserve = min(1.5, 0.1 * duration)  # the final move back down and hold
    first = True
    while True:
        added = False
        kinds = [str(kind) for kind in rng.permutation(_SEGMENT_KINDS)]
        for i, kind in enumerate(kinds):
            budget = duration - used - reserve - 1.0  # 1 s: the longest transition
            if budget <= 0.3:
                break
            if first:  # a fair share, net of the moves between segments
                left = len(kinds) - i
                budget = min(budget, max(1.0, budget / left - 0.6))
            segment = _segment(kind, rng, budget, top)
            if segment is None:
                continue
            start = float(segment(0.0))
            if abs(start - level) > 1e-9 * top:
                move = _transition(level, start, top)
                parts.append(move)
                used += move.duration
            parts.append(segment)
            used += segment.duration
            level = float(segment(segment.duration))
            added = True
        if not (added or first):
            break
        first = False
    remaining = duration - used
    low = rng.uniform(0.0, 0.1) * top
    move = _transition(level, low, top)
    if move.duration < remaining - 1e-9 and abs(low - level) > 1e-9 * top:
        parts.append(move)
        remaining -= move.duration
        level = low
    if remaining > 1e-9:
        parts.append(Constant(level, duration=remaining))
    return Concatenate(parts)


def rich_excitation(
    key: PRNGKeyArray,
    *,
    duration: float = 45.0,
    rate: float = 1000.0,
    amplitude: float = _FULL_SCALE,
) -> InputPath:
    """A rich piezo drive in volts, 0 <= u <= `amplitude`, sampled at `rate` Hz for
    `duration` seconds: a key-dependent random sequence of slow raised cosines
    (0.1-0.5 Hz, large swings), faster ones (2-10 Hz, small swings at various
    offsets), a decaying-amplitude family, a linear chirp sweep (to ~10 Hz),
    triangles, and step-and-hold plateaus (1-3 s holds), joined by smooth moves.

    It starts with a short rest at 0 V and ends with a hold at a low level. The signal
    is continuous (`Concatenate` checks it), and so is its rate except at the
    triangles' and the steps' corners. Short records (under ~20 s) get shorter,
    faster segments, so they still mix rates.
    """
    _check_positive("rich_excitation", "duration", duration)
    _check_positive("rich_excitation", "rate", rate)
    _check_positive("rich_excitation", "amplitude", amplitude)
    rng = _rng(key, "rich_excitation")
    return sample(_rich_signal(rng, float(duration), float(amplitude)), float(rate))


# ------------------------------------------------------ practical excitations


_MIN_SAMPLES_PER_PERIOD = 20  # the fastest sine of a practical drive, at least


def _check_level(owner: str, name: str, value) -> float:
    """A finite number (volts)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        raise TypeError(f"{owner}: {name} must be a number (volts), got {value!r}.")
    if not math.isfinite(value):
        raise ValueError(f"{owner}({name}={value}): {name} must be finite (volts).")
    return float(value)


def _check_swing(owner: str, amplitude: float, offset: float) -> None:
    """The drive offset +- amplitude stays in the stage's 0..100 V range."""
    low, high = offset - amplitude, offset + amplitude
    if low < 0.0 or high > _FULL_SCALE:
        raise ValueError(
            f"{owner}(amplitude={amplitude:g}, offset={offset:g}): the drive swings "
            f"over {low:g}..{high:g} V, outside the piezo stage's unipolar "
            f"0..{_FULL_SCALE:g} V; pass offset >= amplitude and offset + amplitude <= "
            f"{_FULL_SCALE:g}, e.g. amplitude=50.0, offset=50.0."
        )


class AbstractExcitation(eqx.Module):
    """A drive of the kind people record on a piezo stage: a sine or two at one
    amplitude, perhaps after a hold at rest, rather than the `rich_excitation` an
    identification experiment would be designed with.

    `path(duration, rate)` samples it; `describe()` says what it is in words.
    """

    @abc.abstractmethod
    def signal(self, duration: float) -> AbstractSignal:
        """The drive over `duration` seconds (validated by `path`)."""

    @abc.abstractmethod
    def describe(self) -> str:
        """One line: what the drive is."""

    @property
    @abc.abstractmethod
    def highest_frequency(self) -> float:
        """Hz: the fastest sine of the drive (the sampling rate must resolve it)."""

    def path(self, duration: float, rate: float) -> InputPath:
        """The drive sampled at `rate` Hz for `duration` seconds, in volts."""
        owner = f"{type(self).__name__}.path"
        _check_positive(owner, "duration", duration)
        _check_positive(owner, "rate", rate)
        fastest = self.highest_frequency
        if rate < _MIN_SAMPLES_PER_PERIOD * fastest:
            raise ValueError(
                f"{owner}(rate={rate:g}): {rate:g} Hz samples the {fastest:g} Hz sine "
                f"fewer than {_MIN_SAMPLES_PER_PERIOD} times a period; pass rate >= "
                f"{_MIN_SAMPLES_PER_PERIOD * fastest:g}."
            )
        return sample(self.signal(float(duration)), float(rate))


class SineExcitation(AbstractExcitation):
    """One or more sines at one amplitude, summed or played in sequence, each starting
    at rest at the trough `offset - amplitude` (the unipolar convention of
    `RaisedCosine`; defaults 0..100 V):

    - summed (`in_sequence=False`): u(t) = offset - (amplitude / k) * sum_i
      cos(2 pi f_i t), k sines sharing the amplitude, so u stays within offset +-
      amplitude; one frequency gives a plain sine;
    - in sequence (`in_sequence=True`): each frequency in turn for an equal share of
      the record, as many whole periods as fit (each ends at the trough, at rest),
      then a hold at the trough for what is left.

    A record of a few periods (`duration=5.0` at 1 Hz) is a short record.
    """

    frequencies: tuple[float, ...]
    amplitude: float
    offset: float
    in_sequence: bool

    def __init__(
        self,
        frequencies: float | tuple[float, ...] = (1.0,),
        *,
        amplitude: float = 50.0,
        offset: float = 50.0,
        in_sequence: bool = False,
    ):
        owner = "SineExcitation"
        if isinstance(frequencies, (int, float, np.number)):
            frequencies = (frequencies,)
        if isinstance(frequencies, str) or not isinstance(frequencies, (tuple, list)):
            raise TypeError(
                f"{owner}: frequencies must be a tuple of frequencies in Hz, e.g. "
                f"(1.0,) or (1.0, 5.0), got {frequencies!r}."
            )
        if not frequencies:
            raise ValueError(
                f"{owner}(frequencies=()): pass at least one frequency in Hz, e.g. "
                "(1.0,)."
            )
        for f in frequencies:
            _check_positive(owner, "frequencies", f)
        if len(set(frequencies)) != len(frequencies):
            raise ValueError(
                f"{owner}(frequencies={tuple(frequencies)}): a frequency is repeated; "
                "pass each once."
            )
        if not isinstance(in_sequence, bool):
            raise TypeError(
                f"{owner}: in_sequence must be True or False, got {in_sequence!r}."
            )
        _check_positive(owner, "amplitude", amplitude)
        offset = _check_level(owner, "offset", offset)
        _check_swing(owner, float(amplitude), offset)
        self.frequencies = tuple(float(f) for f in frequencies)
        self.amplitude = float(amplitude)
        self.offset = offset
        self.in_sequence = in_sequence

    @property
    def highest_frequency(self) -> float:
        return max(self.frequencies)

    def signal(self, duration: float) -> AbstractSignal:
        owner = "SineExcitation"
        k = len(self.frequencies)
        trough = self.offset - self.amplitude
        if not self.in_sequence:
            slowest = min(self.frequencies)
            if duration * slowest < 1 - 1e-9:
                raise ValueError(
                    f"{owner}: duration={duration:g} s is shorter than one period of "
                    f"the slowest sine ({slowest:g} Hz); pass duration >= "
                    f"{1 / slowest:g}."
                )
            return Multisine(
                np.asarray(self.frequencies),
                np.full(k, self.amplitude / k),
                np.full(k, -math.pi / 2),
                duration=duration,
                offset=self.offset,
            )
        share = duration / k
        parts: list[AbstractSignal] = []
        for f in self.frequencies:
            periods = math.floor(share * f + 1e-9)
            if periods < 1:
                need = k / min(self.frequencies)
                raise ValueError(
                    f"{owner}(in_sequence=True): duration={duration:g} s leaves "
                    f"{share:g} s per frequency, less than one period of {f:g} Hz; "
                    f"pass duration >= {need:g}."
                )
            parts.append(
                RaisedCosine(self.amplitude, f, duration=periods / f, offset=trough)
            )
        left = duration - sum(part.duration for part in parts)
        if left > 1e-9:
            parts.append(Constant(trough, duration=left))
        return Concatenate(parts)

    def describe(self) -> str:
        hz = [f"{f:g}" for f in self.frequencies]
        if len(hz) == 1:
            what = f"sine {hz[0]} Hz"
        elif self.in_sequence:
            what = f"sines {' then '.join(hz)} Hz in sequence"
        else:
            what = f"sum of sines {' + '.join(hz)} Hz"
        low, high = self.offset - self.amplitude, self.offset + self.amplitude
        return f"{what}, {low:g}..{high:g} V, from rest at {low:g} V"


class SwitchOnSine(AbstractExcitation):
    """A drive switched on during the record: a hold at `rest` for `hold` seconds,
    a step to `offset` (a linear rise over `rise` seconds, as an amplifier slews),
    then the sine u = offset + amplitude * sin(2 pi frequency t') from the step on.
    Defaults: 0 V for 2 s, then a 1 Hz sine over 0..100 V starting upwards at 50 V.
    """

    frequency: float
    hold: float
    amplitude: float
    offset: float
    rest: float
    rise: float

    def __init__(
        self,
        frequency: float = 1.0,
        *,
        hold: float = 2.0,
        amplitude: float = 50.0,
        offset: float = 50.0,
        rest: float = 0.0,
        rise: float = 0.005,
    ):
        owner = "SwitchOnSine"
        _check_positive(owner, "frequency", frequency)
        _check_positive(owner, "hold", hold)
        _check_positive(owner, "amplitude", amplitude)
        _check_positive(owner, "rise", rise)
        offset = _check_level(owner, "offset", offset)
        rest = _check_level(owner, "rest", rest)
        _check_swing(owner, float(amplitude), offset)
        if not 0.0 <= rest <= _FULL_SCALE:
            raise ValueError(
                f"{owner}(rest={rest:g}): the rest level must lie in the stage's "
                f"0..{_FULL_SCALE:g} V; pass e.g. rest=0.0."
            )
        self.frequency = float(frequency)
        self.hold = float(hold)
        self.amplitude = float(amplitude)
        self.offset = offset
        self.rest = rest
        self.rise = float(rise)

    @property
    def highest_frequency(self) -> float:
        return self.frequency

    def signal(self, duration: float) -> AbstractSignal:
        running = duration - self.hold - self.rise
        if running * self.frequency < 1 - 1e-9:
            need = self.hold + self.rise + 1 / self.frequency
            raise ValueError(
                f"SwitchOnSine: duration={duration:g} s leaves less than one period "
                f"of the {self.frequency:g} Hz sine after the {self.hold:g} s hold; "
                f"pass duration >= {need:g} (or a shorter hold)."
            )
        return Concatenate(
            [
                Constant(self.rest, duration=self.hold),
                StepHold(
                    np.array([self.rest, self.offset]),
                    hold_time=0.0,
                    ramp_time=self.rise,
                ),
                Multisine(
                    np.array([self.frequency]),
                    np.array([self.amplitude]),
                    np.zeros(1),
                    duration=running,
                    offset=self.offset,
                ),
            ]
        )

    def describe(self) -> str:
        low, high = self.offset - self.amplitude, self.offset + self.amplitude
        return (
            f"hold at {self.rest:g} V for {self.hold:g} s, step to {self.offset:g} V "
            f"in {self.rise * 1e3:g} ms, then sine {self.frequency:g} Hz over "
            f"{low:g}..{high:g} V"
        )
