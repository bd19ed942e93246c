"""The piezo model with every effect of the diagnosis catalogue built in.

Each effect's parameters default to zero, and at zero the model is *exactly*
`PiezoBoucWen` (the effects are nested extensions). The diagnosis switches effects on
by freeing their parameters; `dynamic=True` adds the stage's inertia and damping.
"""

import dataclasses
import functools
import operator
from typing import Any, ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.scipy.linalg
import numpy as np
from jaxtyping import Array, Float

from .._inputs import InputPath
from .._smoothing import AbstractSmoothing, ExactSign
from .base import (
    AbstractGainHoldingModel,
    AbstractHysteresisModel,
    BoucWenShape,
    StageDynamics,
    as_parameter,
    held_gains_field,
    hysteretic_rate,
    legendre_drift,
    read_input,
)
from .bouc_wen import PiezoBoucWen, ShiftedDrive, shift_reason


# The creep modes' relaxation times by default (seconds, fastest first).
CREEP_TIMES = (0.03, 0.3, 3.0, 30.0)
# Where the creep modes (fastest first, as in `creep_times`) live in the state.
_CREEP_STATES = (8, 1, 2, 3)
_CREEP_GAINS = ("creep_faster", "creep_fast", "creep_slow", "creep_slower")


class ExtendedPiezo(AbstractGainHoldingModel[ShiftedDrive]):
    """`PiezoBoucWen` plus the catalogue's effects (all off at zero):

    - asymmetry:       hdot += eps*u*sign(udot)  (the paper's Delta_Phi);
                       gamma1 -> gamma1 + skew*sign(h) (the loop saturates at
                       different levels on its two sides);
                       y += quad*(c^2 - c0^2) + cubic*(c^3 - c0^3),
                       c = (u - input_center)/input_scale, c0 its value at u = 0
                       (a static nonlinearity bends one end of the stroke)
    - input_bias:      the hysteresis sees V = w + input_lead*(w - x), w(t) = u(t + phi),
                       x' = (w - x)/input_time: a time shift seen through a
                       first-order network (input_lead = -1: the RC low-pass of an
                       amplifier driving the piezo capacitance; > 0: a phase lead)
    - rate_dependence: hdot *= 1 + rate_gain*|udot|/rate_scale;
                       A1 -> A1*(1 + rate_amplitude*log(1 + |udot|/rate_scale));
                       y += viscous*(u - z)/(viscous_time*rate_scale),
                       z' = (u - z)/viscous_time: a Kelvin-Voigt (viscoelastic)
                       element, ~ viscous*udot/rate_scale below 1/viscous_time
                       (faster cycles saturate sooner, open wider, or lag)
    - creep:           y += creep_faster*(c0 - u) + creep_fast*(c1 - u)
                            + creep_slow*(c2 - u) + creep_slower*(c3 - u),
                       ci' = (u - ci)/tau_i with tau = creep_times (0.03, 0.3, 3,
                       30 s: logarithmic creep spans decades, one mode per decade)
    - drift:           y += offset + trend*s + curvature*(s^2 - 1/3)
                            + wander*(5 s^3 - 3 s)/2  (Legendre terms),
                       s = (t - time_center)/time_scale in [-1, 1]
    - dynamics:        with `dynamic=True`, y is the static response seen through
                       ydd/omega^2 + (2 zeta/omega) yd + y = y_static (omega from
                       natural_frequency, zeta = damping_ratio)

    The *_center/*_scale fields normalise the effects to the recording and are not
    fitted. State: (h, c1, c2, c3, y_dyn, yd_dyn, z, x, c0).
    """

    k1: Float[Array, ""] = eqx.field(converter=as_parameter)
    k2: Float[Array, ""] = eqx.field(converter=as_parameter)
    A1: Float[Array, ""] = eqx.field(converter=as_parameter)
    beta1: Float[Array, ""] = eqx.field(converter=as_parameter)
    gamma1: Float[Array, ""] = eqx.field(converter=as_parameter)
    n: Float[Array, ""] = eqx.field(converter=as_parameter)
    eps: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    quad: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    cubic: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    skew: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    phi: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    input_lead: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    input_time: Float[Array, ""] = eqx.field(converter=as_parameter, default=1e-2)
    rate_gain: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    viscous: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    rate_amplitude: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    viscous_time: Float[Array, ""] = eqx.field(converter=as_parameter, default=1e-3)
    creep_faster: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    creep_fast: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    creep_slow: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    creep_slower: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    offset: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    trend: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    curvature: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    wander: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    natural_frequency: Float[Array, ""] = eqx.field(converter=as_parameter, default=1e3)
    damping_ratio: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.7)
    input_center: Float[Array, ""] = eqx.field(
        converter=as_parameter, default=0.0, kw_only=True
    )
    input_scale: Float[Array, ""] = eqx.field(
        converter=as_parameter, default=1.0, kw_only=True
    )
    rate_scale: Float[Array, ""] = eqx.field(
        converter=as_parameter, default=1.0, kw_only=True
    )
    time_center: Float[Array, ""] = eqx.field(
        converter=as_parameter, default=0.0, kw_only=True
    )
    time_scale: Float[Array, ""] = eqx.field(
        converter=as_parameter, default=1.0, kw_only=True
    )
    creep_times: tuple[float, float, float, float] = eqx.field(
        default=CREEP_TIMES, static=True, kw_only=True
    )
    dynamic: bool = eqx.field(default=False, static=True, kw_only=True)
    smoothing: AbstractSmoothing = eqx.field(default_factory=ExactSign, kw_only=True)
    # Gains held at zero (`held_at_zero`): their terms, and the states only they
    # read, are not computed (the shifted input with phi held, the log of the rate
    # with rate_amplitude held, each creep mode with its gain held, ...).
    zero_gains: frozenset[str] = held_gains_field()

    state_size: ClassVar[int] = 9
    # The Kelvin-Voigt element relaxes faster than creep's fastest mode: slower, it
    # would be the same equation as a creep mode (a first-order lag of the drive
    # added to the output), and the two effects would share a term.
    parameter_ceilings: ClassVar[dict[str, float]] = {"viscous_time": CREEP_TIMES[0]}

    @classmethod
    def around(
        cls,
        base: AbstractHysteresisModel,
        inputs: InputPath,
        *,
        dynamic: bool = False,
    ) -> "ExtendedPiezo":
        """All effects off around a fitted piezo model, normalised to `inputs`."""
        params: dict[str, Any] = {
            k: base.parameters()[k] for k in PiezoBoucWen.parameter_names
        }
        u = inputs.values
        rate = jnp.diff(u) / inputs.dt
        return cls(
            **params,
            input_center=(jnp.max(u) + jnp.min(u)) / 2,
            input_scale=jnp.maximum((jnp.max(u) - jnp.min(u)) / 2, 1e-30),
            rate_scale=jnp.maximum(jnp.sqrt(jnp.mean(rate**2)), 1e-30),
            time_center=(inputs.t0 + inputs.t1) / 2,
            time_scale=(inputs.t1 - inputs.t0) / 2,
            # Short: a nearly pure dashpot until a refit finds the element's time.
            viscous_time=4 * inputs.dt,
            dynamic=dynamic,
            smoothing=base.smoothing,
        )

    def with_dynamics(self, natural_frequency, damping_ratio) -> "ExtendedPiezo":
        """The same model seen through the stage's inertia and damping."""
        return dataclasses.replace(
            self,
            dynamic=True,
            natural_frequency=natural_frequency,
            damping_ratio=damping_ratio,
        )

    def bouc_wen_shape(self) -> BoucWenShape:
        """(A1, beta1, gamma1, n) of the base law (skew = 0, no rate effects)."""
        return BoucWenShape(
            self.A1,
            self.beta1,
            self.gamma1,
            self.n,
            names=("A1", "beta1", "gamma1", "n"),
        )

    def lag_reason(self) -> str | None:
        """The time shift's where phi != 0, else the stage's with `dynamic`."""
        shifted = shift_reason(self)
        if shifted is not None or not self.dynamic:
            return shifted
        return "this ExtendedPiezo has stage dynamics (inertia and damping)"

    def time_shift(self) -> float:
        return float(self.phi)

    def stage_dynamics(self) -> StageDynamics | None:
        """With `dynamic`: the stage at natural_frequency and damping_ratio, and the
        drift (`drift`) added after it."""
        if not self.dynamic:
            return None
        return StageDynamics(
            2 * np.pi * float(self.natural_frequency),
            float(self.damping_ratio),
            lambda t: np.asarray(self.drift(jnp.asarray(t))),
        )

    def quasi_static(self) -> "ExtendedPiezo":
        """The model with phi = 0 and without the stage (`dynamic=False`)."""
        model = self.replace(phi=0.0)
        if model.dynamic:
            model = dataclasses.replace(model, dynamic=False)
        return model

    def drive(self, path, t, interval=None, frac=None) -> ShiftedDrive:
        u, udot = read_input(path, t, interval, frac)
        if self._holds("phi"):
            return ShiftedDrive(u, udot, u, udot)
        if interval is None or frac is None:
            v, vdot = path.evaluate(t + self.phi)
        else:
            v, vdot = path.on_interval_shifted(interval, frac, self.phi)
        return ShiftedDrive(u, udot, v, vdot)

    def _static_output(self, t, state, drive):
        u = drive.u
        centred = (u - self.input_center) / self.input_scale
        # Static terms vanish at zero input, so they add no offset (that is drift).
        at_rest = -self.input_center / self.input_scale
        terms = [self.k1 * u, self.k2 * state[0]]
        if not self._holds("quad"):
            terms.append(self.quad * (centred**2 - at_rest**2))
        if not self._holds("cubic"):
            terms.append(self.cubic * (centred**3 - at_rest**3))
        if not self._holds("viscous"):
            rate = (u - state[6]) / (self.viscous_time * self.rate_scale)
            terms.append(self.viscous * rate)
        for gain, i in zip(_CREEP_GAINS, _CREEP_STATES, strict=True):
            if not self._holds(gain):
                terms.append(getattr(self, gain) * (state[i] - u))
        return functools.reduce(operator.add, terms)

    def drift(self, t):
        """The output's drift at time `t` (the Legendre terms), added after the
        stage."""
        s = (t - self.time_center) / self.time_scale
        terms = (self._gain(name) for name in ("trend", "curvature", "wander"))
        return self._gain("offset") + legendre_drift(s, *terms)

    def vector_field(self, t, state, drive: ShiftedDrive):
        s = self.smoothing
        h = state[0]
        zero = jnp.zeros_like(h)
        gamma = self.gamma1
        if not self._holds("skew"):
            gamma = gamma + self.skew * s.sign(h)
        relative_rate = s.abs(drive.udot) / self.rate_scale
        amplitude = self.A1
        if not self._holds("rate_amplitude"):
            amplitude = amplitude * (1 + self.rate_amplitude * jnp.log1p(relative_rate))
        if self._holds("input_lead"):
            # x only shapes the network, which is then a wire.
            input_rate, seen_rate = zero, drive.vdot
        else:
            input_rate = (drive.v - state[7]) / self.input_time
            seen_rate = drive.vdot + self.input_lead * (drive.vdot - input_rate)
        hdot = hysteretic_rate(s, h, seen_rate, amplitude, self.beta1, gamma, self.n)
        if not self._holds("rate_gain"):
            hdot = hdot * (1 + self.rate_gain * relative_rate)
        if not self._holds("eps"):
            hdot = hdot + self.eps * drive.u * s.sign(drive.udot)
        # A creep mode (or the viscous element) whose gain is held is not read: its
        # state rests where it started.
        faster, fast, slow, slower = (
            zero if self._holds(gain) else (drive.u - state[i]) / tau
            for gain, i, tau in zip(
                _CREEP_GAINS, _CREEP_STATES, self.creep_times, strict=True
            )
        )
        viscous_rate = (
            zero if self._holds("viscous") else (drive.u - state[6]) / self.viscous_time
        )
        # The stage (y, yd) is propagated exactly per sample in `sample_update`.
        return jnp.stack(
            [hdot, fast, slow, slower, zero, zero, viscous_rate, input_rate, faster]
        )

    def sample_update(self, inputs):
        """With `dynamic=True`: the stage ydd/omega^2 + (2 zeta/omega) yd + y = y_s,
        propagated exactly over each sample interval for a static response y_s that
        is linear between samples (first-order hold: exact for any resonance up to
        and beyond Nyquist, at the cost of one 2x2 update per sample)."""
        if not self.dynamic:
            return None
        dt = inputs.dt
        dtype = inputs.values.dtype
        omega = 2 * jnp.pi * jnp.asarray(self.natural_frequency, dtype)
        zeta = jnp.asarray(self.damping_ratio, dtype)
        zero, one = jnp.zeros((), dtype), jnp.ones((), dtype)
        # d/ds [x, r, q] = [A x + B r, q/dt, 0] with r the static response, q its
        # change over the interval; expm of this generator gives the hold map.
        generator = jnp.stack(
            [
                jnp.stack([zero, one, zero, zero]),
                jnp.stack([-(omega**2), -2 * zeta * omega, omega**2, zero]),
                jnp.stack([zero, zero, zero, one / dt]),
                jnp.stack([zero, zero, zero, zero]),
            ]
        )
        hold = jax.scipy.linalg.expm(generator * dt)
        transition, from_level, from_change = hold[:2, :2], hold[:2, 2], hold[:2, 3]

        def update(start, end, interval):
            def static(state, frac):
                t = inputs.t0 + (interval + frac) * dt
                drive = self.drive(inputs, t, interval, frac)
                return self._static_output(t, state, drive)

            level = static(start, zero)
            change = static(end, one) - level
            stage = transition @ start[4:6] + from_level * level + from_change * change
            return end.at[4:6].set(stage)

        return update

    def has_sample_update(self, inputs):
        # Without building the hold map (its matrix exponential).
        return self.dynamic

    def output(self, t, state, drive):
        if self.dynamic:
            response = state[4]
        else:
            response = self._static_output(t, state, drive)
        return response + self.drift(t)

    def initial_state(self, drive):
        u = jnp.asarray(drive.u)
        zero = jnp.zeros_like(u)
        v = jnp.asarray(drive.v) if isinstance(drive, ShiftedDrive) else u
        state = jnp.stack([zero, u, u, u, zero, zero, u, v, u])
        if self.dynamic:
            state = state.at[4].set(self._static_output(0.0, state, drive))
        return state
