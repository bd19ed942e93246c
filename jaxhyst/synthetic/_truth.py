"""The piezo truth: the model behind a concealed recording, and its base.

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
"""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, PRNGKeyArray

from .._models.base import (
    AbstractHysteresisModel,
    BoucWenShape,
    Drive,
    as_parameter,
    hysteretic_rate,
)
from .._models.bouc_wen import PiezoBoucWen
from .._signals import _check
from .._smoothing import AbstractSmoothing
from .._stability import bibo_stability
from ._random import _rng


_FULL_SCALE = 100.0  # volts in, micrometres out (nominal gain ~1 um/V)
_CREEP_MODES = 8
_CREEP_TIMES = tuple(float(x) for x in np.geomspace(0.05, 30.0, _CREEP_MODES))


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
