"""The MR damper of fixed field (`BoucWenDamper`) with the damper family's effects
built in: what a controllable damper's record shows beyond it.

With every effect's gain at zero it is exactly `BoucWenDamper`,

    F    = c0*xdot + k0*(x - x0) + alpha*z + f0
    zdot = A*xdot - beta*|xdot|*|z|^(n-1)*z - gamma*xdot*|z|^n,

which ignores the command. The effects (the *_scale and time_* fields are
normalisers set by `around` from the record, not fitted):

- field_dependence: the force parameters follow the field s,
  alpha -> alpha*(1 + field_alpha*s), c0 -> c0*(1 + field_damping*s), and the
  internal dashpot of `rolloff` grows by the same factor as c0 (both are the
  fluid's viscous resistance); s = q/(1 + field_knee*q), q = |w|/command_scale
  (field_knee = 0: affine in the command; > 0: the field saturates, as the coil's
  iron and the fluid's yield stress do; < 0: it grows faster than affine, as the
  yield stress does at low fields);
- driver_lag: the field follows the command v through first-order dynamics,
  w' = (v - w)/command_lag (0: w = v), integrated exactly over each sample interval
  for a piecewise-linear command (`sample_update`);
- rolloff: a dashpot c1 = damping_scale/rolloff in series with the Bouc-Wen element
  and c0 (Spencer et al. 1997's internal dashpot, without their internal spring):
  ydot = (alpha*z + c0*xdot)/(c0 + c1), z is driven by xdot - ydot, and the block
  transmits c1*ydot = (alpha*z + c0*xdot)/(1 + c0/c1) (rolloff = 0: rigid, y fixed);
  the force then rolls off at low velocity near reversals;
- offset: the force's zero moves along the record (the accumulator's preload as the
  gas warms, a load-cell zero drifting): F += trend*s + curvature*(s^2 - 1/3) +
  wander*(5 s^3 - 3 s)/2 + legendre4*P4(s) + legendre5*P5(s), s the time in
  [-1, 1] (the Legendre polynomials of degree 1 to 5; the constant is the base's
  f0);
- asymmetry: compression and extension differ: gamma -> gamma +
  skew*(beta + gamma)*sign(z) (the hysteretic force saturates at different levels
  on the two sides) and c0 -> c0*(1 + damping_skew*sign(xdot)) (the valving damps
  one direction more).

State: (z, w), w held over each sample interval and updated exactly at its end (the
RK4 stages inside it read w from the same exact solution).
"""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from .._inputs import InputPath
from .._smoothing import AbstractSmoothing, ExactSign
from .base import (
    AbstractHysteresisModel,
    BoucWenShape,
    as_parameter,
    hysteretic_rate,
    read_input,
)
from .damper import (
    BoucWenDamper,
    DamperDrive,
    _hysteretic_rate_bound,
    _peak_rate,
    _substeps,
    read_command,
)


def _field(default: float):
    return eqx.field(converter=as_parameter, default=default)


def _normaliser(default: float):
    return eqx.field(converter=as_parameter, default=default, kw_only=True)


class LaggedCommandDrive(DamperDrive):
    """`DamperDrive` plus where in its sample interval it is read: the command at
    the interval's start (`v_start`) and the time since it (`elapsed`), from which
    the lagged field is solved exactly inside the interval."""

    v_start: Float[Array, ""]
    elapsed: Float[Array, ""]


class ExtendedDamper(AbstractHysteresisModel):
    """`BoucWenDamper` plus the damper family's effects (all off at zero): field
    dependence, driver lag, roll-off, offset drift and asymmetry. Reads the
    displacement and the command (`input_names`). See the module docstring for the
    equations; build one around a fitted base with `ExtendedDamper.around`."""

    c0: Float[Array, ""] = eqx.field(converter=as_parameter)
    k0: Float[Array, ""] = eqx.field(converter=as_parameter)
    x0: Float[Array, ""] = eqx.field(converter=as_parameter)
    alpha: Float[Array, ""] = eqx.field(converter=as_parameter)
    f0: Float[Array, ""] = eqx.field(converter=as_parameter)
    A: Float[Array, ""] = eqx.field(converter=as_parameter)
    beta: Float[Array, ""] = eqx.field(converter=as_parameter)
    gamma: Float[Array, ""] = eqx.field(converter=as_parameter)
    n: Float[Array, ""] = eqx.field(converter=as_parameter)
    field_alpha: Float[Array, ""] = _field(0.0)
    field_damping: Float[Array, ""] = _field(0.0)
    field_knee: Float[Array, ""] = _field(0.0)
    command_lag: Float[Array, ""] = _field(0.0)
    rolloff: Float[Array, ""] = _field(0.0)
    trend: Float[Array, ""] = _field(0.0)
    curvature: Float[Array, ""] = _field(0.0)
    wander: Float[Array, ""] = _field(0.0)
    skew: Float[Array, ""] = _field(0.0)
    damping_skew: Float[Array, ""] = _field(0.0)
    legendre4: Float[Array, ""] = _field(0.0)
    legendre5: Float[Array, ""] = _field(0.0)
    command_scale: Float[Array, ""] = _normaliser(1.0)
    damping_scale: Float[Array, ""] = _normaliser(1.0)
    time_center: Float[Array, ""] = _normaliser(0.0)
    time_scale: Float[Array, ""] = _normaliser(1.0)
    smoothing: AbstractSmoothing = eqx.field(default_factory=ExactSign, kw_only=True)

    parameter_names: ClassVar[tuple[str, ...]] = (
        *BoucWenDamper.parameter_names,
        "field_alpha",
        "field_damping",
        "field_knee",
        "command_lag",
        "rolloff",
        "trend",
        "curvature",
        "wander",
        "skew",
        "damping_skew",
        "legendre4",
        "legendre5",
    )
    state_size: ClassVar[int] = 2
    input_names: ClassVar[tuple[str, ...]] = ("displacement", "command")

    @classmethod
    def around(
        cls,
        base: AbstractHysteresisModel,
        inputs: InputPath,
        output_scale: float,
    ) -> "ExtendedDamper":
        """All effects off around a fitted `BoucWenDamper` (or `ExtendedDamper`),
        normalised to `inputs` (displacement and command) and `output_scale` (a
        typical force, e.g. the record's RMS force): the field is measured in units
        of the record's peak |command|, the roll-off's compliance in units of
        output_scale/rms(xdot) (a typical force per velocity), the time in half the
        record's duration about its middle."""
        if not isinstance(base, (BoucWenDamper, ExtendedDamper)):
            raise TypeError(
                "ExtendedDamper.around: base must be a BoucWenDamper or an "
                f"ExtendedDamper, got {type(base).__name__}."
            )
        if inputs.channels is None:
            raise ValueError(
                "ExtendedDamper.around: the input path carries the displacement "
                "only; the extended damper also reads the command: build the path "
                "from a Recording with more_inputs={'command': ...} (or InputPath("
                "..., channels=...))."
            )
        x = jnp.asarray(inputs.values)
        command = jnp.asarray(inputs.channels[..., 0, :])
        velocity = jnp.diff(x, axis=-1) / inputs.dt
        peak = jnp.max(jnp.abs(command))
        rms_velocity = jnp.sqrt(jnp.mean(velocity**2))
        values = {
            name: base.parameters()[name] for name in BoucWenDamper.parameter_names
        }
        return cls(
            **values,
            command_scale=jnp.where(peak > 0, peak, 1.0),
            damping_scale=jnp.maximum(output_scale, 1e-30)
            / jnp.maximum(rms_velocity, 1e-30),
            time_center=(inputs.t0 + inputs.t1) / 2,
            time_scale=(inputs.t1 - inputs.t0) / 2,
            smoothing=base.smoothing,
        )

    def base(self) -> BoucWenDamper:
        """The base damper (every effect off) with this model's base parameters."""
        values = {name: getattr(self, name) for name in BoucWenDamper.parameter_names}
        return BoucWenDamper(**values, smoothing=self.smoothing)

    def bouc_wen_shape(self) -> BoucWenShape:
        """(A, beta, gamma, n) of the symmetric law (skew = 0)."""
        return BoucWenShape(
            self.A, self.beta, self.gamma, self.n, names=("A", "beta", "gamma", "n")
        )

    # ------------------------------------------------------------------ the field

    def drive(self, path, t, interval=None, frac=None) -> LaggedCommandDrive:
        x, xdot = read_input(path, t, interval, frac)
        v, vdot = read_command(path, t, interval, frac)
        if interval is None or frac is None:
            position = (jnp.asarray(t, path.dt.dtype) - path.t0) / path.dt
            interval = jnp.clip(jnp.floor(position), 0, path.num_samples - 2).astype(
                jnp.int32
            )
            frac = jnp.clip(position - interval, 0.0, 1.0)
        channels = path.channels
        if channels is None:  # read_command has already refused such a path
            raise ValueError("ExtendedDamper.drive: the path carries no command.")
        v_start = channels[0][interval]
        elapsed = jnp.asarray(frac, path.dt.dtype) * path.dt
        return LaggedCommandDrive(x, xdot, v, vdot, v_start, elapsed)

    def _lagged(self, w_start, v_start, v, vdot, elapsed):
        """The field `elapsed` after the start of a sample interval where it was
        w_start and the command v_start, for a command that is linear inside the
        interval (now v, with rate vdot): the exact solution of w' = (v - w)/lag.
        With lag = 0 it is v (w_start = v_start then): the floor only keeps the
        exponent finite, and the lag's derivative there is -vdot, the first-order
        effect a short lag has."""
        floor = 1e-9 * jnp.abs(self.time_scale)
        decay = jnp.exp(-elapsed / jnp.maximum(self.command_lag, floor))
        return v + (w_start - v_start) * decay - vdot * self.command_lag * (1 - decay)

    def field_strength(self, w: Float[ArrayLike, ""]) -> Float[Array, ""]:
        """s = q/(1 + field_knee*q), q = |w|/command_scale: the field's effect at
        filtered command w (q at field_knee = 0; a negative knee grows faster than
        affine, its denominator floored at 0.05 where it would vanish)."""
        level = jnp.abs(w) / self.command_scale
        return level / jnp.maximum(1 + self.field_knee * level, 0.05)

    def _coefficients(self, w, xdot):
        """(alpha, c0 without the field's growth, that growth, r = rolloff/
        damping_scale) at field w and piston velocity xdot: the internal dashpot is
        c1 = growth/r, so c0/c1 = r*c0 whatever the field."""
        strength = self.field_strength(w)
        alpha = self.alpha * (1 + self.field_alpha * strength)
        grows = 1 + self.field_damping * strength
        c0 = self.c0 * (1 + self.damping_skew * self.smoothing.sign(xdot))
        return alpha, c0, grows, self.rolloff / self.damping_scale

    def _gamma(self, z):
        return self.gamma + self.skew * (self.beta + self.gamma) * self.smoothing.sign(
            z
        )

    # The drive is the one this model's `drive` returns.
    def vector_field(self, t, state, drive: LaggedCommandDrive):  # pyright: ignore[reportIncompatibleMethodOverride]
        z, xdot = state[0], drive.udot
        w = self._lagged(state[1], drive.v_start, drive.v, drive.vdot, drive.elapsed)
        alpha, c0, grows, r = self._coefficients(w, xdot)
        # ydot = (alpha*z + c0*grows*xdot)/(c0*grows + c1), c1 = grows/r.
        ydot = r * (alpha * z / grows + c0 * xdot) / (1 + r * c0)
        zdot = hysteretic_rate(
            self.smoothing,
            z,
            xdot - ydot,
            self.A,
            self.beta,
            self._gamma(z),
            self.n,
        )
        # w is advanced once per sample interval, exactly, by `sample_update`.
        return jnp.stack([zdot, jnp.zeros_like(zdot)])

    def sample_update(self, inputs):
        """The field w at the end of each sample interval: the exact solution of
        w' = (v - w)/command_lag over it for the piecewise-linear command (any lag,
        however short against the sample interval; lag 0 gives w = v). None for a
        path without a command (the simulation then refuses it)."""
        if inputs.channels is None:
            return None
        command = inputs.channels[0]
        dt = inputs.dt

        def update(start, end, interval):
            v_start, v_end = command[interval], command[interval + 1]
            w = self._lagged(start[1], v_start, v_end, (v_end - v_start) / dt, dt)
            return end.at[1].set(w)

        return update

    def output(self, t, state, drive):
        xdot = drive.udot
        alpha, c0, grows, r = self._coefficients(state[1], xdot)
        # The block (Bouc-Wen element beside c0) transmits c1*ydot =
        # (alpha*z + c0*xdot)/(1 + c0/c1); summed in `BoucWenDamper.output`'s order,
        # so that with every effect off the sums round alike.
        share = 1 / (1 + r * c0)
        s = (t - self.time_center) / self.time_scale
        return (
            c0 * grows * xdot * share
            + self.k0 * (drive.u - self.x0)
            + alpha * state[0] * share
            + self.f0
            + self.trend * s
            + self.curvature * (s**2 - 1.0 / 3.0)
            + self.wander * (5 * s**3 - 3 * s) / 2
            + self.legendre4 * (35 * s**4 - 30 * s**2 + 3) / 8
            + self.legendre5 * (63 * s**5 - 70 * s**3 + 15 * s) / 8
        )

    def initial_state(self, drive: DamperDrive):  # pyright: ignore[reportIncompatibleMethodOverride]
        v = jnp.asarray(drive.v)
        return jnp.stack([jnp.zeros_like(v), v])

    # ---------------------------------------------------------------- stiffness

    def stiffness(self, velocity: float, commands: tuple[float, ...] = (0.0,)) -> float:
        """An estimate (1/s) of the fastest rate of zdot at velocities up to
        `velocity`, the largest over the filtered `commands` given: the hysteretic
        term's n*(beta + gamma)*(1 + |skew|)*z_u^(n-1)*|xdot| (as
        `BoucWenDamper.stiffness`) plus the relaxation through the internal dashpot,
        A*alpha/(c0 + c1) at the strongest field. Needs concrete values."""
        p = {name: float(value) for name, value in self.parameters().items()}
        scale = float(self.command_scale)
        damping = float(self.damping_scale)
        beta = p["beta"] * (1 + abs(p["skew"]))
        gamma = p["gamma"] * (1 + abs(p["skew"]))
        fastest = _hysteretic_rate_bound(p["A"], beta, gamma, p["n"], abs(velocity))
        relax = 0.0
        for w in commands:
            level = abs(w) / scale
            strength = level / max(1 + p["field_knee"] * level, 1e-30)
            alpha = abs(p["alpha"] * (1 + p["field_alpha"] * strength))
            grows = max(1 + p["field_damping"] * strength, 1e-30)
            c0 = abs(p["c0"]) * grows * (1 + abs(p["damping_skew"]))
            compliance = abs(p["rolloff"]) / (damping * grows)
            relax = max(relax, abs(p["A"]) * alpha * compliance / (1 + compliance * c0))
        return fastest + relax

    def recommended_substeps(self, inputs: InputPath, *, per_step: float = 1.75) -> int:
        """RK4 substeps per sample interval for `inputs`, as
        `BoucWenDamper.recommended_substeps` (the field's lag is exact per sample and
        adds none). Needs concrete parameter values."""
        if inputs.channels is None:
            commands = (0.0,)
        else:
            v = np.asarray(inputs.channels[0])
            commands = (float(np.min(v)), float(np.max(v)))
        rate = self.stiffness(_peak_rate(inputs), commands)
        return _substeps(rate, float(inputs.dt), per_step)
