"""Excitation signals u(t): the paper's inputs and the standard identification inputs.

A signal is a callable `u = signal(t)` on `[0, signal.duration]`, vectorised over any
shape of `t` and differentiable in `t` (and in its array-valued coefficients), so it
runs under `jax.jit`, `jax.grad` and `jax.vmap`. Durations and other timing that fix
the number of samples are static Python floats; amplitudes, frequencies and offsets
may be traced. Outside `[0, duration]` a signal's formula simply continues
(`StepHold` holds its end levels; `Concatenate` continues its first and last parts).

Convention for the periodic builders (`RaisedCosine`, `DecayingCosine`, `Triangle`,
`Chirp`): they start at rest at `offset` and swing up to `offset + 2 * amplitude`,
like the paper's unipolar u1 = 2 - 2 cos(0.2 pi t), so `amplitude` is half the
peak-to-peak swing. Use `sample(signal, rate)` to turn a signal into an `InputPath`.
"""

import abc
import math
from typing import TYPE_CHECKING, ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, PRNGKeyArray, Real

from ._inputs import AbstractInterpolation, InputPath


_TWO_PI = 2 * math.pi


def _as_time(t: Real[ArrayLike, "..."]) -> Float[Array, "..."]:
    t = jnp.asarray(t)
    if not jnp.issubdtype(t.dtype, jnp.floating):
        t = t.astype(jnp.result_type(float))
    return t


def _float_array(x: Real[ArrayLike, "..."]) -> Float[Array, "..."]:
    x = jnp.asarray(x)
    if not jnp.issubdtype(x.dtype, jnp.floating):
        x = x.astype(jnp.result_type(float))
    return x


def _concrete(x) -> np.ndarray | None:
    """`x` as a NumPy array, or None when it is traced (validation is then skipped)."""
    try:
        return np.asarray(x, dtype=float)
    except (jax.errors.TracerArrayConversionError, jax.errors.ConcretizationTypeError):
        return None


def _check(
    owner: str, name: str, value, condition: str, fix: str = "pass a finite number."
) -> None:
    """Raise a ValueError naming `owner(name=value)` when a concrete `value` fails
    `condition` ("positive", "non-negative" or "finite")."""
    array = _concrete(value)
    if array is None:
        return
    if condition == "positive":
        ok = np.all(array > 0)
    elif condition == "non-negative":
        ok = np.all(array >= 0)
    else:
        ok = True
    ok = ok and np.all(np.isfinite(array))
    if not ok:
        shown = value if array.ndim == 0 else array
        must = condition if condition == "finite" else f"{condition} and finite"
        raise ValueError(f"{owner}({name}={shown}): {name} must be {must}; {fix}")


def _check_duration(owner: str, duration: float) -> None:
    if not (duration > 0 and math.isfinite(duration)):
        raise ValueError(
            f"{owner}(duration={duration}): duration must be positive and finite "
            "(seconds); pass the length of the excitation, e.g. duration=10.0."
        )


class AbstractSignal(eqx.Module):
    """An excitation u(t) defined on `[0, duration]`.

    `signal(t)` accepts any shape of `t` and returns u of the same shape.
    """

    if TYPE_CHECKING:
        # An AbstractVar is a dataclass field to a type checker (see _models/base.py).
        duration: ClassVar[float]
    else:
        duration: eqx.AbstractVar[float]

    @abc.abstractmethod
    def __call__(self, t: Real[ArrayLike, "*shape"]) -> Float[Array, "*shape"]:
        """The input u at times `t` (seconds from the start of the signal)."""


class Constant(AbstractSignal):
    """u(t) = value: a hold, e.g. between two parts of a `Concatenate`."""

    value: float | Float[Array, ""]
    duration: float = eqx.field(static=True, converter=float, kw_only=True)

    def __check_init__(self):
        _check("Constant", "value", self.value, "finite", "pass a finite level.")
        _check_duration("Constant", self.duration)

    def __call__(self, t):
        t = _as_time(t)
        return self.value + jnp.zeros_like(t)


class RaisedCosine(AbstractSignal):
    """u(t) = offset + amplitude * (1 - cos(2 pi frequency t)).

    Starts at rest at `offset`, peaks at `offset + 2 * amplitude` after half a period.
    The paper's inputs are `paper_u1()` and `paper_u2()`.
    """

    amplitude: float | Float[Array, ""]
    frequency: float | Float[Array, ""]
    duration: float = eqx.field(static=True, converter=float, kw_only=True)
    offset: float | Float[Array, ""] = eqx.field(default=0.0, kw_only=True)

    def __check_init__(self):
        _check("RaisedCosine", "amplitude", self.amplitude, "finite")
        _check(
            "RaisedCosine",
            "frequency",
            self.frequency,
            "positive",
            "pass the cycle rate in Hz, e.g. frequency=0.1.",
        )
        _check("RaisedCosine", "offset", self.offset, "finite")
        _check_duration("RaisedCosine", self.duration)

    def __call__(self, t):
        t = _as_time(t)
        return self.offset + self.amplitude * (
            1 - jnp.cos(_TWO_PI * self.frequency * t)
        )


def paper_u1(*, periods: int | float = 1) -> RaisedCosine:
    """The paper's identification input u1(t) = 2 - 2 cos(0.2 pi t): 0.1 Hz, 0 to 4,
    over `periods` periods of 10 s each."""
    if not periods > 0:
        raise ValueError(
            f"paper_u1(periods={periods}): periods must be positive, e.g. periods=1."
        )
    return RaisedCosine(2.0, 0.1, duration=10.0 * periods)


def paper_u2(*, periods: int | float = 1) -> RaisedCosine:
    """The paper's second input u2(t) = 4 - 4 cos(0.2 pi t): 0.1 Hz, 0 to 8,
    over `periods` periods of 10 s each (the paper uses several)."""
    if not periods > 0:
        raise ValueError(
            f"paper_u2(periods={periods}): periods must be positive, e.g. periods=3."
        )
    return RaisedCosine(4.0, 0.1, duration=10.0 * periods)


class DecayingCosine(AbstractSignal):
    """u(t) = offset + amplitude * exp(-t / decay_time) * (1 - cos(2 pi frequency t)).

    Starts at rest at `offset`; every cycle returns to `offset` while its peak shrinks
    by exp(-1 / (frequency * decay_time)), so the hysteresis loops form a nested family
    that shares its lower turning point and shrinks toward `offset`.
    """

    amplitude: float | Float[Array, ""]
    frequency: float | Float[Array, ""]
    decay_time: float | Float[Array, ""]
    duration: float = eqx.field(static=True, converter=float, kw_only=True)
    offset: float | Float[Array, ""] = eqx.field(default=0.0, kw_only=True)

    def __check_init__(self):
        _check("DecayingCosine", "amplitude", self.amplitude, "finite")
        _check(
            "DecayingCosine",
            "frequency",
            self.frequency,
            "positive",
            "pass the cycle rate in Hz, e.g. frequency=0.1.",
        )
        _check(
            "DecayingCosine",
            "decay_time",
            self.decay_time,
            "positive",
            "pass the e-folding time of the envelope in seconds; use RaisedCosine "
            "for a constant amplitude.",
        )
        _check("DecayingCosine", "offset", self.offset, "finite")
        _check_duration("DecayingCosine", self.duration)

    def __call__(self, t):
        t = _as_time(t)
        envelope = self.amplitude * jnp.exp(-t / self.decay_time)
        return self.offset + envelope * (1 - jnp.cos(_TWO_PI * self.frequency * t))


class Triangle(AbstractSignal):
    """A raised triangle wave: rises linearly from `offset` to `offset + 2 * amplitude`
    over the first half period and falls back over the second (slope
    +-4 amplitude frequency). The piecewise-linear counterpart of `RaisedCosine`."""

    amplitude: float | Float[Array, ""]
    frequency: float | Float[Array, ""]
    duration: float = eqx.field(static=True, converter=float, kw_only=True)
    offset: float | Float[Array, ""] = eqx.field(default=0.0, kw_only=True)

    def __check_init__(self):
        _check("Triangle", "amplitude", self.amplitude, "finite")
        _check(
            "Triangle",
            "frequency",
            self.frequency,
            "positive",
            "pass the cycle rate in Hz, e.g. frequency=0.1.",
        )
        _check("Triangle", "offset", self.offset, "finite")
        _check_duration("Triangle", self.duration)

    def __call__(self, t):
        cycles = self.frequency * _as_time(t)
        frac = cycles - jnp.floor(cycles)
        return self.offset + 2 * self.amplitude * (1 - jnp.abs(1 - 2 * frac))


class Chirp(AbstractSignal):
    """A raised swept cosine u(t) = offset + amplitude * (1 - cos(phi(t))) whose
    instantaneous frequency phi'(t) / (2 pi) goes from `f0` at t = 0 to `f1` at
    t = duration, linearly in time or, with `logarithmic=True`, geometrically
    (equal time per octave)."""

    f0: float | Float[Array, ""]
    f1: float | Float[Array, ""]
    amplitude: float | Float[Array, ""]
    duration: float = eqx.field(static=True, converter=float, kw_only=True)
    offset: float | Float[Array, ""] = eqx.field(default=0.0, kw_only=True)
    logarithmic: bool = eqx.field(default=False, static=True, kw_only=True)

    def __check_init__(self):
        condition = "positive" if self.logarithmic else "non-negative"
        fix = (
            "a logarithmic sweep needs f0 > 0 and f1 > 0 (Hz)."
            if self.logarithmic
            else "pass frequencies in Hz."
        )
        _check("Chirp", "f0", self.f0, condition, fix)
        _check("Chirp", "f1", self.f1, condition, fix)
        f0, f1 = _concrete(self.f0), _concrete(self.f1)
        if f0 is not None and f1 is not None and np.all(f0 == 0) and np.all(f1 == 0):
            raise ValueError(
                "Chirp(f0=0, f1=0): at least one of f0, f1 must be positive; use "
                "Constant for a constant input."
            )
        _check("Chirp", "amplitude", self.amplitude, "finite")
        _check("Chirp", "offset", self.offset, "finite")
        _check_duration("Chirp", self.duration)

    def phase(self, t: Real[ArrayLike, "*shape"]) -> Float[Array, "*shape"]:
        """phi(t) in radians, with phi(0) = 0."""
        t = _as_time(t)
        if not self.logarithmic:
            rate = (self.f1 - self.f0) / self.duration
            return _TWO_PI * (self.f0 * t + 0.5 * rate * t * t)
        # phi = 2 pi f0 T / ln(k) (k^(t/T) - 1) = 2 pi f0 t expm1(s) / s, s = ln(k) t/T
        s = jnp.log(self.f1 / self.f0) * t / self.duration
        small = jnp.abs(s) < 1e-4
        safe_s = jnp.where(small, 1.0, s)
        ratio = jnp.where(small, 1 + s / 2 + s * s / 6, jnp.expm1(safe_s) / safe_s)
        return _TWO_PI * self.f0 * t * ratio

    def instantaneous_frequency(
        self, t: Real[ArrayLike, "*shape"]
    ) -> Float[Array, "*shape"]:
        """The instantaneous frequency phi'(t) / (2 pi) in Hz."""
        t = _as_time(t)
        if not self.logarithmic:
            return self.f0 + (self.f1 - self.f0) * t / self.duration
        return self.f0 * (self.f1 / self.f0) ** (t / self.duration)

    def __call__(self, t):
        return self.offset + self.amplitude * (1 - jnp.cos(self.phase(t)))


class Multisine(AbstractSignal):
    """u(t) = offset + sum_k amplitudes[k] * sin(2 pi frequencies[k] t + phases[k]).

    For a periodic excitation pick frequencies that are whole multiples of
    1 / duration. `Multisine.random_phase` builds one with a prescribed RMS.
    """

    frequencies: Float[Array, " k"] = eqx.field(converter=_float_array)
    amplitudes: Float[Array, " k"] = eqx.field(converter=_float_array)
    phases: Float[Array, " k"] = eqx.field(converter=_float_array)
    duration: float = eqx.field(static=True, converter=float, kw_only=True)
    offset: float | Float[Array, ""] = eqx.field(default=0.0, kw_only=True)

    def __check_init__(self):
        shape = self.frequencies.shape
        if len(shape) != 1 or shape[0] == 0:
            raise ValueError(
                f"Multisine: frequencies must be a non-empty 1-D array, got shape "
                f"{shape}; pass one frequency per component."
            )
        for name in ("amplitudes", "phases"):
            other = getattr(self, name).shape
            if other != shape:
                raise ValueError(
                    f"Multisine: {name} has shape {other} but frequencies has shape "
                    f"{shape}; pass one {name[:-1]} per frequency."
                )
        _check(
            "Multisine",
            "frequencies",
            self.frequencies,
            "positive",
            "pass component frequencies in Hz (use offset for the mean).",
        )
        _check("Multisine", "amplitudes", self.amplitudes, "finite")
        _check("Multisine", "phases", self.phases, "finite")
        _check("Multisine", "offset", self.offset, "finite")
        _check_duration("Multisine", self.duration)

    @classmethod
    def random_phase(
        cls,
        key: PRNGKeyArray,
        frequencies: Float[ArrayLike, " k"],
        *,
        rms: float | Float[Array, ""],
        duration: float,
        offset: float | Float[Array, ""] = 0.0,
    ) -> "Multisine":
        """Equal-amplitude multisine with phases uniform in [0, 2 pi) drawn from `key`.

        The amplitudes `rms * sqrt(2 / k)` give an RMS about `offset` of exactly `rms`
        when the frequencies are distinct whole multiples of 1 / duration, and close
        to it otherwise.
        """
        frequencies = _float_array(frequencies)
        _check(
            "Multisine.random_phase",
            "rms",
            rms,
            "positive",
            "pass the target root-mean-square of u - offset.",
        )
        concrete = _concrete(frequencies)
        if (
            concrete is not None
            and concrete.ndim == 1
            and np.unique(concrete).size != concrete.size
        ):
            raise ValueError(
                f"Multisine.random_phase(frequencies={concrete}): frequencies must be "
                "distinct for the RMS to hold; remove the duplicates."
            )
        num = frequencies.shape[0] if frequencies.ndim == 1 else 0
        amplitudes = jnp.full(
            frequencies.shape, rms * math.sqrt(2 / max(num, 1)), frequencies.dtype
        )
        phases = jax.random.uniform(
            key, frequencies.shape, frequencies.dtype, minval=0.0, maxval=_TWO_PI
        )
        return cls(frequencies, amplitudes, phases, duration=duration, offset=offset)

    def __call__(self, t):
        t = _as_time(t)
        lead = (1,) * t.ndim
        frequencies = self.frequencies.reshape(lead + self.frequencies.shape)
        amplitudes = self.amplitudes.reshape(lead + self.amplitudes.shape)
        phases = self.phases.reshape(lead + self.phases.shape)
        angle = _TWO_PI * frequencies * t[..., None] + phases
        return self.offset + jnp.sum(amplitudes * jnp.sin(angle), axis=-1)


class StepHold(AbstractSignal):
    """A staircase through `levels`: hold `levels[0]` for `hold_time`, then for each
    next level ramp to it linearly over `ramp_time` and hold it for `hold_time`.

    `duration = len(levels) * hold_time + (len(levels) - 1) * ramp_time`; level `i`
    is held on `[i * (hold_time + ramp_time), i * (hold_time + ramp_time) + hold_time]`.
    Use it for creep and drift tests; `hold_time=0` gives a piecewise-linear path.
    """

    levels: Float[Array, " n"] = eqx.field(converter=_float_array)
    hold_time: float = eqx.field(static=True, converter=float, kw_only=True)
    ramp_time: float = eqx.field(static=True, converter=float, kw_only=True)

    def __check_init__(self):
        shape = self.levels.shape
        if len(shape) != 1 or shape[0] < 2:
            raise ValueError(
                f"StepHold: levels must be a 1-D array of at least 2 levels, got shape "
                f"{shape}; use Constant for a single level."
            )
        _check("StepHold", "levels", self.levels, "finite")
        if not (self.hold_time >= 0 and math.isfinite(self.hold_time)):
            raise ValueError(
                f"StepHold(hold_time={self.hold_time}): hold_time must be non-negative "
                "and finite (seconds)."
            )
        if not (self.ramp_time > 0 and math.isfinite(self.ramp_time)):
            raise ValueError(
                f"StepHold(ramp_time={self.ramp_time}): ramp_time must be positive "
                "and finite; a true step has an unbounded rate, so use a short ramp."
            )

    @property
    def duration(self) -> float:
        num = self.levels.shape[0]
        return num * self.hold_time + (num - 1) * self.ramp_time

    def __call__(self, t):
        t = _as_time(t)
        num = self.levels.shape[0]
        period = self.hold_time + self.ramp_time
        index = jnp.clip(jnp.floor(t / period), 0, num - 1).astype(jnp.int32)
        local = t - index * period
        here = self.levels[index]
        after = self.levels[jnp.minimum(index + 1, num - 1)]
        progress = (local - self.hold_time) / self.ramp_time
        progress = jnp.where(progress < 0, 0.0, jnp.where(progress > 1, 1.0, progress))
        return here + (after - here) * progress


class Concatenate(AbstractSignal):
    """Plays `signals` one after another, each in its own local time starting at 0;
    `duration` is the sum of theirs.

    Raises a ValueError at construction if one signal ends more than `atol` away from
    where the next starts, unless `allow_jumps=True`. The default `atol` is
    sqrt(machine epsilon) times max(1, |u| at the junction).
    """

    signals: tuple[AbstractSignal, ...] = eqx.field(converter=tuple)
    allow_jumps: bool = eqx.field(default=False, static=True, kw_only=True)
    atol: float | None = eqx.field(default=None, static=True, kw_only=True)

    def __check_init__(self):
        if len(self.signals) == 0:
            raise ValueError("Concatenate: signals is empty; pass at least one signal.")
        for i, signal in enumerate(self.signals):
            if not isinstance(signal, AbstractSignal):
                raise ValueError(
                    f"Concatenate: signals[{i}] is a {type(signal).__name__}, not a "
                    "signal; wrap arrays with a signal class first."
                )
        if self.atol is not None and not self.atol >= 0:
            raise ValueError(
                f"Concatenate(atol={self.atol}): atol must be non-negative, or None "
                "for the default."
            )
        if self.allow_jumps:
            return
        start = 0.0
        for i in range(len(self.signals) - 1):
            first, second = self.signals[i], self.signals[i + 1]
            start += first.duration
            with jax.ensure_compile_time_eval():  # check concrete parts under jit too
                end, begin = first(first.duration), second(0.0)
            left, right = _concrete(end), _concrete(begin)
            if left is None or right is None:
                continue  # traced coefficients: nothing to check at construction
            if self.atol is None:
                dtype = jnp.result_type(end, begin)
                tol = math.sqrt(float(jnp.finfo(dtype).eps)) * max(
                    1.0, abs(float(left)), abs(float(right))
                )
            else:
                tol = self.atol
            jump = float(right) - float(left)
            if not abs(jump) <= tol:
                raise ValueError(
                    f"Concatenate: jump of {jump:.6g} at junction {i} (t={start:.6g}): "
                    f"signals[{i}] ({type(first).__name__}) ends at {float(left):.6g} "
                    f"but signals[{i + 1}] ({type(second).__name__}) starts at "
                    f"{float(right):.6g}; match the levels (e.g. with offset) or pass "
                    "allow_jumps=True."
                )

    @property
    def duration(self) -> float:
        return sum(signal.duration for signal in self.signals)

    def __call__(self, t):
        t = _as_time(t)
        last = len(self.signals) - 1
        values, starts = [], []
        start = 0.0
        for i, signal in enumerate(self.signals):
            local = t - start
            # Clamp local time to the part's own interval (except outwards at the two
            # ends), so an unselected part is never evaluated far outside it, where it
            # could overflow and poison gradients through `where`.
            if i > 0:
                local = jnp.where(local < 0, 0.0, local)
            if i < last:
                local = jnp.where(local > signal.duration, signal.duration, local)
            values.append(signal(local))
            starts.append(start)
            start += signal.duration
        out = values[0]
        for start, value in zip(starts[1:], values[1:], strict=True):
            out = jnp.where(t >= start, value, out)
        return out


def _num_samples(signal: AbstractSignal, rate: float, owner: str) -> int:
    if not isinstance(signal, AbstractSignal):
        raise ValueError(
            f"{owner}: signal is a {type(signal).__name__}, not an AbstractSignal; "
            "build one with RaisedCosine, Multisine, ... first."
        )
    if isinstance(rate, bool) or not isinstance(rate, (int, float, np.number)):
        raise ValueError(
            f"{owner}(rate={rate!r}): rate must be a Python number (samples per "
            "second); it fixes the number of samples, so it cannot be traced."
        )
    if not (rate > 0 and math.isfinite(rate)):
        raise ValueError(
            f"{owner}(rate={rate}): rate must be positive and finite (samples per "
            "second), e.g. rate=1000.0."
        )
    num = round(signal.duration * float(rate)) + 1
    if num < 2:
        raise ValueError(
            f"{owner}(rate={rate}): a {signal.duration:g} s signal gives only {num} "
            "sample; raise the rate to at least 1 / duration."
        )
    return num


@eqx.filter_jit
def _evaluate(signal: AbstractSignal, t: Float[Array, " n"]) -> Float[Array, " n"]:
    """`signal(t)` as one program (op by op, a signal's few operations compile one
    small program each per record length)."""
    return signal(t)


def sample_times(signal: AbstractSignal, rate: float) -> np.ndarray:
    """The sample times `k / rate` for `k = 0, ..., round(duration * rate)` (so the
    last time equals `duration` whenever `duration * rate` is a whole number)."""
    num = _num_samples(signal, rate, "sample_times")
    return np.arange(num, dtype=float) / float(rate)


def sample(
    signal: AbstractSignal,
    rate: float,
    *,
    interpolation: AbstractInterpolation | None = None,
) -> InputPath:
    """`signal` sampled at `sample_times(signal, rate)` as an `InputPath` starting at
    t = 0 (linear interpolation between samples unless `interpolation` says
    otherwise). The paper samples u1 at `rate=1000.0`."""
    num = _num_samples(signal, rate, "sample")
    times = np.arange(num, dtype=float) / float(rate)
    values = _evaluate(signal, jnp.asarray(times))
    return InputPath(0.0, 1.0 / float(rate), values, interpolation=interpolation)
