"""Synthetic piezo recordings that conceal missing physics, with a known truth.

The diagnosis ("locate the mismatch, name the missing physics, add it, show the fit
improve") has to be proven on records where an effect is *concealed*: tens of seconds
of rich excitation in which one effect (or two) changes the output by only a few noise
standard deviations, so that the hysteresis loop looks ordinary to the eye, and on
clean records, where nothing may be flagged.

The truth is deliberately *not* written in the diagnosis catalogue's own equations
(`ExtendedPiezo`): every effect below has a different functional form, so a diagnosis
that names it has recognised the physics, not its own template.

==================  ==========================================================
effect              truth form (one variant per record, chosen by the key)
==================  ==========================================================
asymmetry           `BranchBeta`: beta1 differs between ascending and
                    descending branches; or `CubicStatic`: a static cubic
                    y += c*(((u - u_c)/U)^3 - ...) around an off-centre u_c
input_bias          `PhaseFilter`: the hysteresis sees u through a first-order
                    rational filter (1 + s*(lag + shift))/(1 + s*lag): a Pade
                    all-pass delay, or a lead (advance), of `shift` seconds
rate_dependence     `RateAmplitude`: A1 -> A1*(1 + a*sqrt(|Vdot|/R)); or
                    `KelvinElement`: a viscous Kelvin element in series
creep               `PronyCreep`: logarithmic creep as a Prony series of 8
                    relaxation modes from 0.05 s to 30 s, driven by u
dynamics            `ModalResonance`: a stage mode at 30-150 Hz (damping ratio
                    0.05-0.4) seen with participation lambda (a two-mass stage)
drift               `ThermalDrift`: a saturating exponential plus a sinusoid
                    whose period is longer than the record; independent of u
==================  ==========================================================

Each effect's size is *set*: its coefficient is rescaled (exactly where the output
is linear in it, by a safeguarded secant search where it is not) until the RMS of
(y with the effect - y without it) equals the requested number of noise sigmas.
"""

import abc
import math
from collections.abc import Callable, Mapping
from typing import ClassVar, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, PRNGKeyArray

from ._inputs import InputPath
from ._models.base import (
    AbstractHysteresisModel,
    BoucWenShape,
    Drive,
    as_parameter,
    hysteretic_rate,
)
from ._models.bouc_wen import PiezoBoucWen
from ._recording import Recording
from ._signals import (
    AbstractSignal,
    Chirp,
    Concatenate,
    Constant,
    DecayingCosine,
    Multisine,
    RaisedCosine,
    StepHold,
    Triangle,
    _check,
    sample,
)
from ._simulate import RK4, simulate
from ._smoothing import AbstractSmoothing
from ._stability import bibo_stability


EFFECTS: tuple[str, ...] = (
    "asymmetry",
    "input_bias",
    "rate_dependence",
    "creep",
    "dynamics",
    "drift",
)
NOISE_KINDS: tuple[str, ...] = ("white", "coloured")

_FULL_SCALE = 100.0  # volts in, micrometres out (nominal gain ~1 um/V)
_CREEP_MODES = 8
_CREEP_TIMES = tuple(float(x) for x in np.geomspace(0.05, 30.0, _CREEP_MODES))
_MAX_NATURAL_FREQUENCY = 150.0  # Hz, the fastest mode the truth may carry
_MIN_FILTER_LAG = 2e-3  # s, the fastest pole of the input-bias filter
_DEFAULT_SIZES = (3.0, 10.0)  # noise sigmas, when size_sigmas is None


# ------------------------------------------------------------------ truth forms


class BranchBeta(eqx.Module):
    """asymmetry (hysteresis level): beta depends on the branch,

        beta = beta1 * (1 + split * sign(Vdot)),

    so the ascending and descending branches saturate at different levels and the loop
    loses its point symmetry. `split = 0` is off. Any |split| <= 1 keeps the
    paper-like class (A1 < 0, beta1 - gamma1 > 0) BIBO-stable.
    """

    split: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)

    def beta(self, beta1, vdot, smoothing: AbstractSmoothing):
        return beta1 * (1 + self.split * smoothing.sign(vdot))


class CubicStatic(eqx.Module):
    """asymmetry (static): a cubic static nonlinearity around an off-centre input,

        y += coefficient * (w^3 - w0^3 - slope * u / scale),
        w = (u - centre) / scale,  w0 = -centre / scale,

    zero at u = 0; `slope` removes the part a refit of k1 would absorb on the record
    it was built for. `coefficient` is in output units; 0 is off.
    """

    coefficient: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    centre: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    scale: Float[Array, ""] = eqx.field(converter=as_parameter, default=1.0)
    slope: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)

    def __check_init__(self):
        _check("CubicStatic", "scale", self.scale, "positive", "pass the input span.")

    def term(self, u):
        w = (u - self.centre) / self.scale
        w0 = -self.centre / self.scale
        return self.coefficient * (w**3 - w0**3 - self.slope * u / self.scale)


class PhaseFilter(eqx.Module):
    """input_bias: the hysteresis sees V = G(s) u with the first-order rational filter

        G(s) = (1 + s*(lag + shift)) / (1 + s*lag),

    i.e. V = u + (shift/lag)*(u - x), x' = (u - x)/lag. At low frequency V(t) ~
    u(t + shift): `shift < 0` with lag = |shift|/2 is the Pade all-pass delay,
    `shift > 0` a phase lead (advance). `shift = 0` is off (V = u exactly).
    """

    shift: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    lag: Float[Array, ""] = eqx.field(converter=as_parameter, default=1.0)

    def __check_init__(self):
        _check("PhaseFilter", "lag", self.lag, "positive", "pass seconds, e.g. 0.01.")

    def read(self, x, u, udot):
        """(V, Vdot, xdot) from the filter state `x` and the input."""
        c = self.shift / self.lag
        xdot = (u - x) / self.lag
        return u + c * (u - x), udot + c * (udot - xdot), xdot


class RateAmplitude(eqx.Module):
    """rate_dependence (hysteresis level): the hysteresis amplitude grows with the
    rate, A1 -> A1 * (1 + gain * sqrt(|Vdot| / rate_scale)), so faster cycles give
    wider loops. `gain = 0` is off."""

    gain: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    rate_scale: Float[Array, ""] = eqx.field(converter=as_parameter, default=1.0)

    def __check_init__(self):
        _check("RateAmplitude", "rate_scale", self.rate_scale, "positive")

    def amplitude(self, A1, vdot):
        return A1 * (1 + self.gain * jnp.sqrt(jnp.abs(vdot) / self.rate_scale))


class KelvinElement(eqx.Module):
    """rate_dependence (output level): a viscous Kelvin element in series,

        y += gain * (z - u),   z' = (u - z) / tau,

    which lags the output by ~gain*tau*udot at low rates and saturates above 1/tau.
    `gain = 0` is off."""

    gain: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    tau: Float[Array, ""] = eqx.field(converter=as_parameter, default=1.0)

    def __check_init__(self):
        _check("KelvinElement", "tau", self.tau, "positive", "pass seconds.")


class PronyCreep(eqx.Module):
    """creep: logarithmic creep approximated by a Prony series of relaxation modes,

        y += coefficient * sum_i weights_i * (z_i - u),   z_i' = (u - z_i) / times_i,

    with times spread over decades (0.05 s to 30 s); after a step the output keeps
    growing roughly with log(t). `coefficient = 0` is off."""

    coefficient: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    times: Float[Array, " modes"] = eqx.field(
        converter=as_parameter, default=_CREEP_TIMES
    )
    weights: Float[Array, " modes"] = eqx.field(
        converter=as_parameter, default=(1.0 / _CREEP_MODES,) * _CREEP_MODES
    )

    def __check_init__(self):
        for name in ("times", "weights"):
            shape = getattr(self, name).shape
            if shape != (_CREEP_MODES,):
                raise ValueError(
                    f"PronyCreep: {name} must have shape ({_CREEP_MODES},), got "
                    f"{shape}; pass one value per relaxation mode."
                )
        _check("PronyCreep", "times", self.times, "positive", "pass seconds.")


class ModalResonance(eqx.Module):
    """dynamics: a stage mode of `natural_frequency` (Hz) and `damping_ratio`, seen
    by the sensor with participation `participation` (a two-mass stage):

        q'' = omega^2 (y_s - q) - 2 zeta omega q',   y = y_s + participation*(q - y_s),

    with y_s the quasi-static output. `participation = 0` is off."""

    participation: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    natural_frequency: Float[Array, ""] = eqx.field(converter=as_parameter, default=1.0)
    damping_ratio: Float[Array, ""] = eqx.field(converter=as_parameter, default=1.0)

    def __check_init__(self):
        _check(
            "ModalResonance", "natural_frequency", self.natural_frequency, "positive"
        )
        _check("ModalResonance", "damping_ratio", self.damping_ratio, "positive")


class ThermalDrift(eqx.Module):
    """drift: thermal drift, independent of the input,

        d(t) = scale * ((1 - exp(-t/time_constant))
                        + sine_ratio * (sin(2 pi t/period + phase) - sin(phase))),

    zero at t = 0. `scale = 0` is off."""

    scale: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    time_constant: Float[Array, ""] = eqx.field(converter=as_parameter, default=1.0)
    sine_ratio: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    period: Float[Array, ""] = eqx.field(converter=as_parameter, default=1.0)
    phase: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)

    def __check_init__(self):
        _check("ThermalDrift", "time_constant", self.time_constant, "positive")
        _check("ThermalDrift", "period", self.period, "positive")

    def __call__(self, t):
        settle = -jnp.expm1(-t / self.time_constant)
        wave = jnp.sin(2 * jnp.pi * t / self.period + self.phase) - jnp.sin(self.phase)
        return self.scale * (settle + self.sine_ratio * wave)


class ConcealedTruth(AbstractHysteresisModel):
    """The model that generates a concealed recording: the quasi-static piezo model
    `base` (y = k1*u + k2*h, eq. 7-8) with every truth form of this module built in
    and off by default (then it is exactly `base`):

        V, Vdot  = PhaseFilter(u)                                  (input_bias)
        hdot     = (A - (beta*sign(Vdot)*sign(h) + gamma1)*|h|^n) * Vdot,
                   A = RateAmplitude(A1, Vdot), beta = BranchBeta(beta1, Vdot)
        y_s      = k1*u + k2*h + CubicStatic(u) + KelvinElement + PronyCreep
        y        = ModalResonance(y_s) + ThermalDrift(t)

    State (13): h, the filter state x, the Kelvin state z, 8 creep states, and the
    mode's (q, q'). Its `parameters()` are the base's six; the effects' coefficients
    live in the effect fields. The fastest time scales (150 Hz mode, 2 ms filter lag)
    need `RK4(substeps=...)` with substeps >= 2*pi*150*dt/0.25.
    """

    base: PiezoBoucWen
    shape: BranchBeta = eqx.field(default_factory=BranchBeta)
    input_filter: PhaseFilter = eqx.field(default_factory=PhaseFilter)
    rate_amplitude: RateAmplitude = eqx.field(default_factory=RateAmplitude)
    cubic: CubicStatic = eqx.field(default_factory=CubicStatic)
    kelvin: KelvinElement = eqx.field(default_factory=KelvinElement)
    creep: PronyCreep = eqx.field(default_factory=PronyCreep)
    resonance: ModalResonance = eqx.field(default_factory=ModalResonance)
    drift: ThermalDrift = eqx.field(default_factory=ThermalDrift)

    parameter_names: ClassVar[tuple[str, ...]] = PiezoBoucWen.parameter_names
    state_size: ClassVar[int] = 5 + _CREEP_MODES

    @property
    def smoothing(self) -> AbstractSmoothing:
        return self.base.smoothing

    # The base parameters, so that `parameters()` and `replace()` read the
    # underlying piezo model.
    @property
    def k1(self):
        return self.base.k1

    @property
    def k2(self):
        return self.base.k2

    @property
    def A1(self):
        return self.base.A1

    @property
    def beta1(self):
        return self.base.beta1

    @property
    def gamma1(self):
        return self.base.gamma1

    @property
    def n(self):
        return self.base.n

    def bouc_wen_shape(self) -> BoucWenShape:
        """The base model's shape (what `bibo_stability` checks)."""
        return self.base.bouc_wen_shape()

    def _quasi_static(self, state, drive: Drive):
        u = drive.u
        z, creep = state[2], state[3 : 3 + _CREEP_MODES]
        return (
            self.base.k1 * u
            + self.base.k2 * state[0]
            + self.cubic.term(u)
            + self.kelvin.gain * (z - u)
            + self.creep.coefficient * jnp.sum(self.creep.weights * (creep - u))
        )

    def vector_field(self, t, state, drive):
        b = self.base
        u, udot = drive.u, drive.udot
        h, x, z = state[0], state[1], state[2]
        creep = state[3 : 3 + _CREEP_MODES]
        q, qd = state[3 + _CREEP_MODES], state[4 + _CREEP_MODES]
        v, vdot, xdot = self.input_filter.read(x, u, udot)
        del v  # the Bouc-Wen law reads only the rate of what it sees
        amplitude = self.rate_amplitude.amplitude(b.A1, vdot)
        beta = self.shape.beta(b.beta1, vdot, self.smoothing)
        hdot = hysteretic_rate(self.smoothing, h, vdot, amplitude, beta, b.gamma1, b.n)
        zdot = (u - z) / self.kelvin.tau
        creep_dot = (u - creep) / self.creep.times
        omega = 2 * jnp.pi * self.resonance.natural_frequency
        y_s = self._quasi_static(state, drive)
        qdd = omega**2 * (y_s - q) - 2 * self.resonance.damping_ratio * omega * qd
        return jnp.concatenate(
            [jnp.stack([hdot, xdot, zdot]), creep_dot, jnp.stack([qd, qdd])]
        )

    def output(self, t, state, drive):
        y_s = self._quasi_static(state, drive)
        q = state[3 + _CREEP_MODES]
        return y_s + self.resonance.participation * (q - y_s) + self.drift(t)

    def initial_state(self, drive):
        u = jnp.asarray(drive.u)
        zero = jnp.zeros_like(u)
        rest = jnp.concatenate(
            [
                jnp.stack([zero, u, u]),
                jnp.full(_CREEP_MODES, u),
                jnp.stack([zero, zero]),
            ]
        )
        return rest.at[3 + _CREEP_MODES].set(self._quasi_static(rest, drive))


# ---------------------------------------------------------------- the excitation


def _rng(key: PRNGKeyArray, owner: str) -> np.random.Generator:
    """A NumPy generator seeded from a JAX key (typed or legacy uint32)."""
    if key is None or not hasattr(key, "dtype"):
        raise TypeError(
            f"{owner}: key must be a JAX PRNG key, e.g. jax.random.key(0), got "
            f"{type(key).__name__}; there is no default key."
        )
    if jnp.issubdtype(key.dtype, jax.dtypes.prng_key):
        data = jax.random.key_data(key)
    elif key.dtype == jnp.uint32 and key.shape == (2,):
        data = key
    else:
        raise TypeError(
            f"{owner}: key must be a JAX PRNG key, e.g. jax.random.key(0), got an "
            f"array of dtype {key.dtype} and shape {key.shape}."
        )
    return np.random.default_rng(np.asarray(data, dtype=np.uint32).ravel().tolist())


def _loguniform(rng: np.random.Generator, low: float, high: float) -> float:
    return float(np.exp(rng.uniform(np.log(low), np.log(high))))


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


def _check_positive(owner: str, name: str, value) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        raise TypeError(f"{owner}: {name} must be a number, got {value!r}.")
    if not (value > 0 and math.isfinite(value)):
        raise ValueError(
            f"{owner}({name}={value}): {name} must be positive and finite."
        )


# --------------------------------------------------------------- the base truth


def _major_loop(
    n: float, beta1: float, gamma1: float, top: float, steps: int = 400
) -> tuple[float, float]:
    """For A1 = -1, integrate dh/du = A1 - (beta1*s*sign(h) + gamma1)*|h|^n (s the
    direction of u) up 0 -> top from h = 0, down to 0 and up again. Returns h at the
    top of the first ascent and the largest gap between the descending and the second
    ascending branch (the major loop's width in h)."""

    def branch(h: float, s: float, start: float, end: float) -> np.ndarray:
        slope = lambda h: -1.0 - (beta1 * s * np.sign(h) + gamma1) * abs(h) ** n
        du = (end - start) / steps
        out = [h]
        for _ in range(steps):
            k1 = slope(h)
            k2 = slope(h + du * k1 / 2)
            k3 = slope(h + du * k2 / 2)
            k4 = slope(h + du * k3)
            h += du * (k1 + 2 * k2 + 2 * k3 + k4) / 6
            out.append(h)
        return np.asarray(out)

    up = branch(0.0, 1.0, 0.0, top)
    down = branch(up[-1], -1.0, top, 0.0)
    again = branch(down[-1], 1.0, 0.0, top)
    return float(up[-1]), float(np.max(down[::-1] - again))


def base_truth(key: PRNGKeyArray) -> PiezoBoucWen:
    """A paper-like quasi-static piezo model (eq. 7-8) with u in volts and y in
    micrometres, about 0..100 um for 0..100 V, randomised around a nominal set:

    - gauge A1 = -1 (h in volts) with the paper's signs, A1 < 0 < k2, so the loop runs
      counter-clockwise (the output lags the input) as a piezo stage's does;
    - n in [1, 2.5]; the saturation level |h|_sat = (beta1 - gamma1)^(-1/n) in
      [20, 40] V, and (beta1 + gamma1)/(beta1 - gamma1) in [0.05, 0.6] (the paper's
      Table 4 has 0.18): Table 2's stable class A < 0, beta - gamma > 0,
      beta + gamma >= 0 (checked with `bibo_stability`);
    - k2 makes the 0-100 V major loop 10-15 % of the span wide, and k1 sets the gain
      at full scale on the first ascent to 0.85-1.1 um/V.
    """
    rng = _rng(key, "base_truth")
    n = rng.uniform(1.0, 2.5)
    saturation = rng.uniform(20.0, 40.0)
    ratio = rng.uniform(0.05, 0.6)
    width = rng.uniform(0.10, 0.15)
    gain = rng.uniform(0.85, 1.1)
    d = saturation**-n
    beta1, gamma1 = d * (1 + ratio) / 2, -d * (1 - ratio) / 2
    h_top, gap = _major_loop(n, beta1, gamma1, _FULL_SCALE)
    k2 = width * gain * _FULL_SCALE / gap
    k1 = gain - k2 * h_top / _FULL_SCALE
    model = PiezoBoucWen(k1, k2, -1.0, beta1, gamma1, n)
    report = bibo_stability(model)
    if not report:  # pragma: no cover - the construction above is stable
        raise RuntimeError(f"base_truth drew an unstable model: {report.reason}")
    return model


# ----------------------------------------------------------- sizing the effects


def _truth_solver(rate: float) -> RK4:
    """RK4 substeps resolving a 150 Hz mode (omega*h <= 0.25) and the 2 ms filter."""
    dt = 1.0 / rate
    return RK4(
        substeps=max(2, math.ceil(2 * math.pi * _MAX_NATURAL_FREQUENCY * dt / 0.25))
    )


@eqx.filter_jit
def _run_jit(model: ConcealedTruth, path: InputPath, solver: RK4):
    return simulate(model, path, solver)


def _run(model: ConcealedTruth, path: InputPath, solver: RK4) -> np.ndarray:
    """Simulate under one compilation per record shape: the leaves are cast to one
    (strong) dtype first, so weakly and strongly typed coefficients share it."""
    return np.asarray(_run_jit(model.astype(path.values.dtype), path, solver))


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def _solve_size(
    measure: Callable[[float], float],
    target: float,
    start: float,
    *,
    linear: bool,
    most: float = math.inf,
) -> tuple[float, float]:
    """A coefficient p > 0 with measure(p) = target (an RMS), and the RMS reached.

    Exact rescaling where the effect is linear in p; otherwise a secant search in
    log-log coordinates, safeguarded by bisection once the target is bracketed, and
    capped at `most` (the RMS reached is then below the target)."""
    r = measure(start)
    if not r > 0:
        raise RuntimeError("an effect left the output unchanged; cannot size it")
    if linear:
        return start * target / r, target
    points = [(start, r)]
    low = high = None
    p = start
    for _ in range(12):
        if abs(r / target - 1) < 0.005:
            break
        if r < target:
            low = p if low is None else max(low, p)
        else:
            high = p if high is None else min(high, p)
        order = 1.0
        if len(points) >= 2:
            (p0, r0), (p1, r1) = points[-2], points[-1]
            if p0 != p1 and r0 > 0 and r1 > 0:
                order = float(np.clip(np.log(r1 / r0) / np.log(p1 / p0), 0.2, 5.0))
        step = p * (target / r) ** (1 / order)
        if low is not None and high is not None and not low < step < high:
            step = math.sqrt(low * high)
        if step >= most:
            if p >= most:
                break  # capped: the largest allowed size is not enough
            step = most
        p = step
        r = measure(p)
        points.append((p, r))
    return min(points, key=lambda pr: abs(math.log(pr[1] / target)))


class _Context(NamedTuple):
    path: InputPath
    u: np.ndarray
    duration: float
    measure: Callable  # (field name, component) -> RMS of the change it makes


def _size_asymmetry(rng, ctx: _Context, target: float):
    sign = float(rng.choice([-1.0, 1.0]))
    if rng.random() < 0.5:
        make = lambda p: BranchBeta(sign * p)
        p, r = _solve_size(
            lambda p: ctx.measure("shape", make(p)),
            target,
            0.05,
            linear=False,
            most=0.95,
        )
        if r >= 0.98 * target:
            return (
                "shape",
                make(p),
                r,
                f"branch-dependent beta1*(1 + {sign * p:.4g}*sign(Vdot))",
            )
        # The hysteresis is too small for this size: a static asymmetry instead.
    top = float(np.max(ctx.u))
    centre = rng.uniform(0.0, 0.3) * top
    w, w0, v = (ctx.u - centre) / top, -centre / top, ctx.u / top
    slope = float(np.dot(w**3 - w0**3, v) / np.dot(v, v))
    make = lambda p: CubicStatic(sign * p, centre, top, slope)
    p, r = _solve_size(
        lambda p: ctx.measure("cubic", make(p)), target, 1.0, linear=True
    )
    return (
        "cubic",
        make(p),
        r,
        f"static cubic {sign * p:.4g}*(w^3 - w0^3 - {slope:.4g}*u/{top:.4g}), "
        f"w = (u - {centre:.4g})/{top:.4g}",
    )


def _size_input_bias(rng, ctx: _Context, target: float):
    advance = bool(rng.random() < 0.5)

    def make(p):
        lag = max(p if advance else p / 2, _MIN_FILTER_LAG)
        return PhaseFilter(p if advance else -p, lag)

    p, r = _solve_size(
        lambda p: ctx.measure("input_filter", make(p)),
        target,
        0.005,
        linear=False,
        most=2.0,
    )
    f = make(p)
    kind = "phase lead (advance)" if advance else "Pade all-pass (delay)"
    return (
        "input_filter",
        f,
        r,
        f"{kind} filter, shift {float(f.shift) * 1e3:.4g} ms, lag {float(f.lag) * 1e3:.4g} ms",
    )


def _size_rate_dependence(rng, ctx: _Context, target: float):
    if rng.random() < 0.5:
        scale = _rms(np.diff(ctx.u) / float(ctx.path.dt))
        make = lambda p: RateAmplitude(p, scale)
        p, r = _solve_size(
            lambda p: ctx.measure("rate_amplitude", make(p)),
            target,
            0.05,
            linear=False,
            most=20.0,
        )
        if r >= 0.98 * target:
            return (
                "rate_amplitude",
                make(p),
                r,
                f"rate-dependent amplitude A1*(1 + {p:.4g}*sqrt(|Vdot|/{scale:.4g} "
                "V/s))",
            )
        # The hysteresis is too small for this size: a Kelvin element instead.
    tau = rng.uniform(0.005, 0.025)
    make = lambda p: KelvinElement(p, tau)
    p, r = _solve_size(
        lambda p: ctx.measure("kelvin", make(p)), target, 0.01, linear=True
    )
    return (
        "kelvin",
        make(p),
        r,
        f"Kelvin element gain {p:.4g} um/V, tau {tau * 1e3:.4g} ms",
    )


def _size_creep(rng, ctx: _Context, target: float):
    tilt = rng.uniform(-0.3, 0.3)
    times = np.asarray(_CREEP_TIMES)
    weights = times**tilt / np.sum(times**tilt)
    make = lambda p: PronyCreep(p, times, weights)
    p, r = _solve_size(
        lambda p: ctx.measure("creep", make(p)), target, 0.01, linear=True
    )
    return (
        "creep",
        make(p),
        r,
        f"Prony creep {p:.4g} um/V over {_CREEP_MODES} modes "
        f"{times[0]:.3g}-{times[-1]:.3g} s, weights ~ tau^{tilt:.3g}",
    )


def _size_dynamics(rng, ctx: _Context, target: float):
    frequency = _loguniform(rng, 30.0, _MAX_NATURAL_FREQUENCY)
    damping = rng.uniform(0.05, 0.4)

    def sized(f, zeta):
        make = lambda p: ModalResonance(p, f, zeta)
        p, r = _solve_size(
            lambda p: ctx.measure("resonance", make(p)), target, 1.0, linear=True
        )
        return make, p, r

    # A participation above 1 would act like a mode below 30 Hz. If the record does
    # not excite the mode enough, soften it to 30 Hz, then damp it up to 0.4 (at these
    # rates the damping's phase lag dominates), and as a last resort show all of it.
    make, p, r = sized(frequency, damping)
    while p > 1.0 and frequency > 30.0:
        frequency = max(30.0, frequency * 0.7)
        make, p, r = sized(frequency, damping)
    while p > 1.0 and damping < 0.4:
        damping = min(0.4, damping * 1.5)
        make, p, r = sized(frequency, damping)
    if p > 1.0:
        p, r = 1.0, ctx.measure("resonance", make(1.0))
    return (
        "resonance",
        make(p),
        r,
        f"stage mode {frequency:.4g} Hz, damping ratio {damping:.3g}, "
        f"participation {p:.4g}",
    )


def _size_drift(rng, ctx: _Context, target: float):
    sign = float(rng.choice([-1.0, 1.0]))
    tc = rng.uniform(0.15, 0.6) * ctx.duration
    ratio = rng.uniform(0.3, 1.0) * rng.choice([-1.0, 1.0])
    period = rng.uniform(1.5, 4.0) * ctx.duration
    phase = rng.uniform(0.0, 2 * math.pi)
    make = lambda p: ThermalDrift(sign * p, tc, ratio, period, phase)
    p, r = _solve_size(
        lambda p: ctx.measure("drift", make(p)), target, 1.0, linear=True
    )
    return (
        "drift",
        make(p),
        r,
        f"thermal drift {sign * p:.4g} um*((1 - exp(-t/{tc:.3g} s)) + {ratio:.3g}*"
        f"(sin(2 pi t/{period:.3g} s + {phase:.3g}) - sin({phase:.3g})))",
    )


_SIZERS = {
    "asymmetry": _size_asymmetry,
    "input_bias": _size_input_bias,
    "rate_dependence": _size_rate_dependence,
    "creep": _size_creep,
    "dynamics": _size_dynamics,
    "drift": _size_drift,
}


# ----------------------------------------------------------------------- noise


def _noise(
    rng: np.random.Generator, kind: str, sigma: float, num: int
) -> tuple[np.ndarray, str]:
    white = rng.standard_normal(num)
    if kind == "white":
        return sigma * white, "white Gaussian"
    if rng.random() < 0.5:
        phi, white_share = rng.uniform(0.9, 0.98), 0.0
    else:
        phi, white_share = rng.uniform(0.93, 0.98), rng.uniform(0.02, 0.08)
    drive = np.sqrt(1 - phi**2) * rng.standard_normal(num)
    drive[0] = rng.standard_normal()  # start in the stationary distribution
    import scipy.signal  # deferred: heavy import, needed only here

    ar = scipy.signal.lfilter([1.0], [1.0, -phi], drive)
    noise = sigma * (np.sqrt(1 - white_share) * ar + np.sqrt(white_share) * white)
    what = f"coloured AR(1), coefficient {phi:.3g}"
    if white_share:
        what += f", plus white noise carrying {white_share:.1%} of the variance"
    return noise, what


# ------------------------------------------------------------------ the cases


class ConcealedCase(eqx.Module):
    """A synthetic recording and the truth behind it.

    - `recording`: the noisy record (u in V, y in um);
    - `effects`: the concealed effects, in catalogue order (empty: a clean record);
    - `sigma`: the noise's marginal standard deviation (um);
    - `sizes`: per effect, the RMS of (y with that effect alone - y without it) in
      units of `sigma`;
    - `truth_description`: the base parameters, each effect's form and coefficients,
      and the noise;
    - `truth`: the `ConcealedTruth` that made the noise-free output, `base` the piezo
      model under it (what a perfect diagnosis recovers), `noiseless` that output,
      `noise` the noise kind, `solver` the integrator used.
    """

    recording: Recording
    effects: tuple[str, ...]
    sigma: float
    sizes: dict[str, float]
    truth_description: str
    truth: ConcealedTruth
    base: PiezoBoucWen
    noiseless: np.ndarray
    noise: str
    solver: RK4


def _validate_effects(effects, owner: str) -> tuple[str, ...]:
    if isinstance(effects, str):
        raise TypeError(
            f"{owner}: effects must be a tuple of effect names, e.g. ({effects!r},), "
            "not a string."
        )
    effects = tuple(effects)
    unknown = [e for e in effects if e not in EFFECTS]
    if unknown:
        raise ValueError(
            f"{owner}: unknown effect(s) {unknown}; valid names are "
            f"{', '.join(EFFECTS)} (an empty tuple gives a clean recording)."
        )
    if len(set(effects)) != len(effects):
        raise ValueError(f"{owner}: effects {effects} name an effect twice.")
    return tuple(e for e in EFFECTS if e in effects)


def _validate_sizes(size_sigmas, effects, owner: str) -> dict[str, float] | None:
    """The requested sizes per effect, or None where they are to be drawn."""
    if size_sigmas is None:
        return None
    if isinstance(size_sigmas, Mapping):
        extra = sorted(set(size_sigmas) - set(effects))
        missing = sorted(set(effects) - set(size_sigmas))
        if extra or missing:
            raise ValueError(
                f"{owner}: size_sigmas names {sorted(size_sigmas)} but the effects "
                f"are {list(effects)}; give one size per effect (or a single number)."
            )
        sizes = {e: size_sigmas[e] for e in effects}
    else:
        sizes = {e: size_sigmas for e in effects}
    for effect, size in sizes.items():
        if isinstance(size, bool) or not isinstance(size, (int, float, np.number)):
            raise TypeError(
                f"{owner}: size of {effect!r} must be a number, got {size!r}."
            )
        if not (size > 0 and math.isfinite(size)):
            raise ValueError(
                f"{owner}: size of {effect!r} is {size}; sizes are positive numbers "
                "of noise sigmas, e.g. size_sigmas=5.0."
            )
    return {e: float(s) for e, s in sizes.items()}


def _validate_arguments(effects, key, noise, size_sigmas, owner: str):
    """Check everything before any work: (effects, noise, sizes or None)."""
    effects = _validate_effects(effects, owner)
    _rng(key, owner)
    if noise == "colored":
        noise = "coloured"
    if noise not in NOISE_KINDS:
        raise ValueError(
            f"{owner}(noise={noise!r}): noise must be one of {', '.join(NOISE_KINDS)}."
        )
    return effects, noise, _validate_sizes(size_sigmas, effects, owner)


def _concealed_case(
    path: InputPath,
    effects: tuple[str, ...],
    key: PRNGKeyArray,
    noise: str,
    size_sigmas,
    name: str,
    owner: str,
    *,
    input_line: str | None = None,
    note_shortfall: bool = False,
) -> ConcealedCase:
    """The case for `effects` on `path`. `input_line`, if given, describes the input
    as the first line of the truth description; with `note_shortfall` an effect that
    stayed below 95 % of its requested size says so in its line."""
    effects, noise, sizes_wanted = _validate_arguments(
        effects, key, noise, size_sigmas, owner
    )
    k_base, k_effects, k_sizes, k_noise = jax.random.split(key, 4)
    effect_rng = lambda root, e: _rng(jax.random.fold_in(root, EFFECTS.index(e)), owner)
    if sizes_wanted is None:
        sizes_wanted = {
            e: float(effect_rng(k_sizes, e).uniform(*_DEFAULT_SIZES)) for e in effects
        }

    base = base_truth(k_base)
    rate = 1.0 / float(path.dt)
    solver = _truth_solver(rate)
    quiet = ConcealedTruth(base)
    y_base = _run(quiet, path, solver)
    noise_rng = _rng(k_noise, owner)
    sigma = _loguniform(noise_rng, 5e-4, 2e-3) * float(np.ptp(y_base))

    def measure(field: str, component) -> float:
        model = eqx.tree_at(lambda m: getattr(m, field), quiet, component)
        return _rms(_run(model, path, solver) - y_base)

    ctx = _Context(path, np.asarray(path.values), float(path.t1 - path.t0), measure)
    components, sizes, lines = {}, {}, []
    for effect in effects:
        target = sizes_wanted[effect] * sigma
        field, component, reached, what = _SIZERS[effect](
            effect_rng(k_effects, effect), ctx, target
        )
        components[field] = component
        sizes[effect] = reached / sigma
        line = f"{effect}: {what}; size {sizes[effect]:.3g} sigma"
        if note_shortfall and reached < 0.95 * target:
            line += (
                f" (requested {sizes_wanted[effect]:.3g} sigma: this input does not "
                "show more of it)"
            )
        lines.append(line)

    truth = ConcealedTruth(base, **components)
    y_true = _run(truth, path, solver) if effects else y_base
    e, what_noise = _noise(noise_rng, noise, sigma, y_true.shape[0])
    t = np.asarray(path.times)
    recording = Recording(
        t,
        np.asarray(path.values),
        y_true + e,
        name=name,
        input_name="u",
        output_name="y",
        input_unit="V",
        output_unit="um",
    )
    p = {k: float(v) for k, v in base.parameters().items()}
    head = (
        f"base: PiezoBoucWen(k1={p['k1']:.5g}, k2={p['k2']:.5g}, A1={p['A1']:.5g}, "
        f"beta1={p['beta1']:.5g}, gamma1={p['gamma1']:.5g}, n={p['n']:.4g}) "
        "[u in V, y in um]"
    )
    tail = (
        f"noise: {what_noise}, sigma {sigma:.4g} um "
        f"({sigma / np.ptp(y_base):.3%} of the output range)"
    )
    body = lines or ["no effects (clean recording)"]
    first = [] if input_line is None else [input_line]
    return ConcealedCase(
        recording=recording,
        effects=effects,
        sigma=sigma,
        sizes=sizes,
        truth_description="\n".join([*first, head, *body, tail]),
        truth=truth,
        base=base,
        noiseless=y_true,
        noise=noise,
        solver=solver,
    )


def concealed_recording(
    effects: tuple[str, ...],
    *,
    key: PRNGKeyArray,
    duration: float = 45.0,
    rate: float = 1000.0,
    noise: str = "white",
    size_sigmas: float | Mapping[str, float] | None = None,
) -> ConcealedCase:
    """A recording of a paper-like piezo stage (`base_truth`) under `rich_excitation`
    that conceals `effects` (names from asymmetry, input_bias, rate_dependence, creep,
    dynamics, drift; `()` gives a clean recording), plus sensor noise.

    Each effect's form differs from the diagnosis catalogue's (see the module
    docstring) and its size is set so that the RMS of the change it makes, alone, is
    `size_sigmas` noise sigmas: one number for all, a mapping per effect, or None to
    draw each from [3, 10]. `noise` is "white" (Gaussian) or "coloured" (AR(1) with
    coefficient 0.9-0.98, sometimes plus a little white noise, at the same marginal
    sigma); sigma is 0.05-0.2 % of the output range.

    `sizes` reports what was reached (within 0.5 % of the request). Where a variant
    cannot reach the request (a branch-dependent beta or a rate-dependent amplitude
    bounded by the hysteresis itself) the other variant of that effect is used; a
    stage mode is never shown with a participation above 1, so on a record with
    little fast content a dynamics effect can come out smaller than requested.

    Everything random follows from `key`: the excitation, the base model, each
    effect's variant and size, and the noise. The same key with different effects
    gives the same input, base and noise, so records differ only by the effects.
    """
    owner = "concealed_recording"
    _check_positive(owner, "duration", duration)
    _check_positive(owner, "rate", rate)
    effects, noise, _ = _validate_arguments(effects, key, noise, size_sigmas, owner)
    k_input, k_case = jax.random.split(key)
    path = rich_excitation(k_input, duration=duration, rate=rate)
    label = "+".join(effects) if effects else "clean"
    return _concealed_case(
        path, effects, k_case, noise, size_sigmas, f"concealed-{label}-{noise}", owner
    )


_DEMO_SEED = 2024


def demo_recording(*, key: PRNGKeyArray | None = None) -> ConcealedCase:
    """The demo record: a paper-like piezo stage under the paper's u2 = 4 - 4 cos(0.2
    pi t), scaled to volts (x12.5: 0..100 V), three periods (30 s) at 1 kHz, whose
    data conceal an asymmetry (8 sigma) and an input bias (6 sigma) under white sensor
    noise. `key=None` uses the bundled default seed, `jax.random.key(2024)`, so the
    demo is the same everywhere; pass a key for another draw.
    """
    if key is None:
        key = jax.random.key(_DEMO_SEED)
    signal = RaisedCosine(4.0 * 12.5, 0.1, duration=30.0)
    path = sample(signal, 1000.0)
    return _concealed_case(
        path,
        ("asymmetry", "input_bias"),
        key,
        "white",
        {"asymmetry": 8.0, "input_bias": 6.0},
        "demo-u2",
        "demo_recording",
    )


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


def practical_recording(
    effects: tuple[str, ...],
    *,
    key: PRNGKeyArray,
    excitation: AbstractExcitation,
    duration: float = 20.0,
    rate: float = 1000.0,
    noise: str = "white",
    size_sigmas: float | Mapping[str, float] | None = None,
) -> ConcealedCase:
    """A recording like the ones people have: the paper-like piezo stage of
    `concealed_recording` under a plain drive, `excitation` (a `SineExcitation` of one
    or two sines, a `SwitchOnSine`; a short `duration` for a short record), sampled
    at `rate` Hz for `duration` seconds, concealing `effects` under sensor noise.

    Effects, sizes and noise follow `concealed_recording` exactly (the same truth
    forms, sizing and noise kinds; `size_sigmas` None draws each size from [3, 10]
    noise sigmas). Everything random follows from `key`; the input is fixed by
    `excitation`, so the same key with different effects gives the same input, base
    and noise, and records differ only by the effects.

    A plain drive shows some effects little: `sizes` reports what was reached, and
    the truth description says when an effect stayed below 95 % of its requested size
    (a stage mode, never shown with a participation above 1, on a slow sine).
    On such records some effects also look alike (a delay of the drive, a rate
    dependence and creep on one sine), which is the point of these records.
    """
    owner = "practical_recording"
    if not isinstance(excitation, AbstractExcitation):
        raise TypeError(
            f"{owner}: excitation must be an excitation object, e.g. "
            "SineExcitation((1.0,)), SineExcitation((1.0, 5.0)) or SwitchOnSine(1.0), "
            f"got {type(excitation).__name__}."
        )
    _check_positive(owner, "duration", duration)
    _check_positive(owner, "rate", rate)
    effects, noise, _ = _validate_arguments(effects, key, noise, size_sigmas, owner)
    path = excitation.path(duration, rate)
    label = "+".join(effects) if effects else "clean"
    return _concealed_case(
        path,
        effects,
        key,
        noise,
        size_sigmas,
        f"practical-{label}-{noise}",
        owner,
        input_line=(
            f"input: {excitation.describe()}; {float(duration):g} s at {float(rate):g} Hz"
        ),
        note_shortfall=True,
    )
