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
- driver_lag: the field follows the command v through two first-order stages in
  series, the current u' = (v - u)/command_lag (the driver and the coil's L/R) and
  the field w' = (u - w)/field_lag (eddy currents, the fluid's response); 0 passes
  a stage through (both 0: w = v). The first stage is integrated exactly over each
  sample interval for a piecewise-linear command, the second exactly for an input
  that moves at the first stage's mean rate over the interval (`sample_update`);
  two stages follow a driver that settles like a second-order system (an S-shaped
  step response) where one stage cannot;
- rolloff: a dashpot c1 = damping_scale/rolloff in series with the Bouc-Wen element
  and c0 (Spencer et al. 1997's internal dashpot, without their internal spring):
  ydot = (alpha*z + c0*xdot)/(c0 + c1), z is driven by xdot - ydot, and the block
  transmits c1*ydot = (alpha*z + c0*xdot)/(1 + c0/c1) (rolloff = 0: rigid, y fixed);
  the force then rolls off at low velocity near reversals;
- offset: the force's zero moves along the record (the accumulator's preload as the
  gas warms, a load-cell zero drifting): F += a uniform cubic B-spline in the time
  s in [-1, 1] over 24 equal intervals (`spline_drift`), coefficients offset1 ...
  offset26 (the first B-spline is left out: the constant is the base's f0). A
  zero that wanders at the scale of a twenty-fourth of the record; refits hold its
  second differences small (the effect's `smooth`), so the spline interpolates
  smoothly where samples are held out;
- asymmetry: compression and extension differ: gamma -> gamma +
  skew*(beta + gamma)*sign(z) (the hysteretic force saturates at different levels
  on the two sides) and c0 -> c0*(1 + damping_skew*sign(xdot)) (the valving damps
  one direction more).

State: (z, u, w), the current u and the field w held over each sample interval and
updated at its end (the RK4 stages inside it read them from the same solution).
"""

from typing import Any, ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from .._inputs import InputPath
from .._recording import Recording
from .._simulate import RK4
from .._smoothing import AbstractSmoothing, ExactSign
from .base import (
    AbstractGainHoldingModel,
    AbstractHysteresisModel,
    BoucWenShape,
    as_parameter,
    held_gains_field,
    hysteretic_rate,
    read_input,
    spline_drift,
)
from .damper import (
    AbstractDamperDrive,
    BoucWenDamper,
    _hysteretic_rate_bound,
    _peak_rate,
    _substeps,
    read_command,
)


def _field(default: float):
    return eqx.field(converter=as_parameter, default=default)


def _normaliser(default: float):
    return eqx.field(converter=as_parameter, default=default, kw_only=True)


# The offset's spline coefficients (the `offset` effect's parameters): 24 equal
# intervals of the record carry 27 cubic B-splines; the first is left out.
OFFSET_INTERVALS = 24
OFFSET_TERMS = tuple(f"offset{k}" for k in range(1, OFFSET_INTERVALS + 3))


class LaggedCommandDrive(AbstractDamperDrive):
    """`DamperDrive`'s displacement, command and their rates, plus where in its
    sample interval it is read: the command at the interval's start (`v_start`) and
    the time since it (`elapsed`), from which the lagged field is solved exactly
    inside the interval."""

    u: Float[Array, ""]
    udot: Float[Array, ""]
    v: Float[Array, ""]
    vdot: Float[Array, ""]
    v_start: Float[Array, ""]
    elapsed: Float[Array, ""]


class ExtendedDamper(AbstractGainHoldingModel[LaggedCommandDrive]):
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
    field_lag: Float[Array, ""] = _field(0.0)
    rolloff: Float[Array, ""] = _field(0.0)
    skew: Float[Array, ""] = _field(0.0)
    damping_skew: Float[Array, ""] = _field(0.0)
    offset1: Float[Array, ""] = _field(0.0)
    offset2: Float[Array, ""] = _field(0.0)
    offset3: Float[Array, ""] = _field(0.0)
    offset4: Float[Array, ""] = _field(0.0)
    offset5: Float[Array, ""] = _field(0.0)
    offset6: Float[Array, ""] = _field(0.0)
    offset7: Float[Array, ""] = _field(0.0)
    offset8: Float[Array, ""] = _field(0.0)
    offset9: Float[Array, ""] = _field(0.0)
    offset10: Float[Array, ""] = _field(0.0)
    offset11: Float[Array, ""] = _field(0.0)
    offset12: Float[Array, ""] = _field(0.0)
    offset13: Float[Array, ""] = _field(0.0)
    offset14: Float[Array, ""] = _field(0.0)
    offset15: Float[Array, ""] = _field(0.0)
    offset16: Float[Array, ""] = _field(0.0)
    offset17: Float[Array, ""] = _field(0.0)
    offset18: Float[Array, ""] = _field(0.0)
    offset19: Float[Array, ""] = _field(0.0)
    offset20: Float[Array, ""] = _field(0.0)
    offset21: Float[Array, ""] = _field(0.0)
    offset22: Float[Array, ""] = _field(0.0)
    offset23: Float[Array, ""] = _field(0.0)
    offset24: Float[Array, ""] = _field(0.0)
    offset25: Float[Array, ""] = _field(0.0)
    offset26: Float[Array, ""] = _field(0.0)
    command_scale: Float[Array, ""] = _normaliser(1.0)
    damping_scale: Float[Array, ""] = _normaliser(1.0)
    time_center: Float[Array, ""] = _normaliser(0.0)
    time_scale: Float[Array, ""] = _normaliser(1.0)
    smoothing: AbstractSmoothing = eqx.field(default_factory=ExactSign, kw_only=True)
    # Gains held at zero (`held_at_zero`): with both lags held the field is the
    # command (no per-stage exponentials: most of a forward pass's cost); with
    # field_alpha and field_damping held no field is computed at all, and with
    # rolloff held no internal dashpot.
    zero_gains: frozenset[str] = held_gains_field()

    state_size: ClassVar[int] = 3
    input_names: ClassVar[tuple[str, ...]] = ("displacement", "command")
    retired_parameters: ClassVar[dict[str, str]] = dict.fromkeys(
        (
            "trend",
            "curvature",
            "wander",
            *(f"legendre{k}" for k in range(4, 9)),
        ),
        "the offset's Legendre terms in time, replaced by the cubic spline "
        "offset1 ... offset26",
    )

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
        values: dict[str, Any] = {
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

    def _time_floor(self):
        # A duration far below any sample interval, which keeps divisions finite.
        return 1e-9 * jnp.abs(self.time_scale)

    def _first_order(self, start, input_start, input_now, input_rate, elapsed, lag):
        """A first-order stage `elapsed` after the start of a sample interval where
        it was `start` and its input `input_start`, for an input moving at
        `input_rate` (now `input_now`): the exact solution of x' = (input - x)/lag.
        With lag = 0 it is the input (start = input_start then): the floor only
        keeps the exponent finite, and the lag's derivative there is -input_rate,
        the first-order effect a short lag has."""
        decay = jnp.exp(-elapsed / jnp.maximum(lag, self._time_floor()))
        return (
            input_now + (start - input_start) * decay - input_rate * lag * (1 - decay)
        )

    def _lagged(self, current, field, v_start, v, vdot, elapsed):
        """(current, field) `elapsed` into a sample interval that started at
        (`current`, `field`) with the command at v_start, for a command that is
        linear inside the interval (now v, with rate vdot). The field's input, the
        current, is taken as moving at its mean rate since the interval's start."""
        if self._holds("command_lag", "field_lag"):
            return v, v
        command_lag, field_lag = self._gain("command_lag"), self._gain("field_lag")
        now = self._first_order(current, v_start, v, vdot, elapsed, command_lag)
        rate = (now - current) / jnp.maximum(elapsed, self._time_floor())
        return now, self._first_order(field, current, now, rate, elapsed, field_lag)

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
        if self._holds("field_alpha", "field_damping"):
            alpha, grows = self.alpha, None
        else:
            strength = self.field_strength(w)
            alpha = self.alpha
            if not self._holds("field_alpha"):
                alpha = alpha * (1 + self.field_alpha * strength)
            grows = None
            if not self._holds("field_damping"):
                grows = 1 + self.field_damping * strength
        c0 = self.c0
        if not self._holds("damping_skew"):
            c0 = c0 * (1 + self.damping_skew * self.smoothing.sign(xdot))
        r = None if self._holds("rolloff") else self.rolloff / self.damping_scale
        return alpha, c0, grows, r

    def _field_at(self, state, drive: LaggedCommandDrive):
        """The field at a stage inside the sample interval (None when no term reads
        it)."""
        if self._holds("field_alpha", "field_damping"):
            return None
        return self._lagged(
            state[1], state[2], drive.v_start, drive.v, drive.vdot, drive.elapsed
        )[1]

    def _gamma(self, z):
        if self._holds("skew"):
            return self.gamma
        return self.gamma + self.skew * (self.beta + self.gamma) * self.smoothing.sign(
            z
        )

    def vector_field(self, t, state, drive: LaggedCommandDrive):
        z, xdot = state[0], drive.udot
        alpha, c0, grows, r = self._coefficients(self._field_at(state, drive), xdot)
        # ydot = (alpha*z + c0*grows*xdot)/(c0*grows + c1), c1 = grows/r.
        if r is None:
            relative = xdot
        else:
            per_growth = alpha * z if grows is None else alpha * z / grows
            relative = xdot - r * (per_growth + c0 * xdot) / (1 + r * c0)
        zdot = hysteretic_rate(
            self.smoothing,
            z,
            relative,
            self.A,
            self.beta,
            self._gamma(z),
            self.n,
        )
        # The current and the field are advanced once per sample interval by
        # `sample_update`.
        zero = jnp.zeros_like(zdot)
        return jnp.stack([zdot, zero, zero])

    def sample_update(self, inputs):
        """The current and the field at the end of each sample interval, from the
        same solution the interval's RK4 stages read (`_lagged`: any lag, however
        short against the sample interval; lags 0 give w = v). None for a path
        without a command (the simulation then refuses it)."""
        if inputs.channels is None:
            return None
        command = inputs.channels[0]
        dt = inputs.dt

        def update(start, end, interval):
            v_start, v_end = command[interval], command[interval + 1]
            current, field = self._lagged(
                start[1], start[2], v_start, v_end, (v_end - v_start) / dt, dt
            )
            return end.at[1].set(current).at[2].set(field)

        return update

    def output(self, t, state, drive):
        xdot = drive.udot
        alpha, c0, grows, r = self._coefficients(state[2], xdot)
        # The block (Bouc-Wen element beside c0) transmits c1*ydot =
        # (alpha*z + c0*xdot)/(1 + c0/c1); summed in `BoucWenDamper.output`'s order,
        # so that with every effect off the sums round alike.
        viscous = c0 * xdot if grows is None else c0 * grows * xdot
        hysteretic = alpha * state[0]
        if r is not None:
            share = 1 / (1 + r * c0)
            viscous, hysteretic = viscous * share, hysteretic * share
        s = (t - self.time_center) / self.time_scale
        return (
            viscous
            + self.k0 * (drive.u - self.x0)
            + hysteretic
            + self.f0
            + spline_drift(s, tuple(self._gain(name) for name in OFFSET_TERMS))
        )

    def initial_state(self, drive: LaggedCommandDrive):
        v = jnp.asarray(drive.v)
        return jnp.stack([jnp.zeros_like(v), v, v])

    # ---------------------------------------------------------------- stiffness

    def default_solver(self, recording: Recording) -> RK4:
        """The damper family's substeps (`DamperFamily.solver`), which `diagnose`
        fits the model with."""
        from .._diagnose._families import DamperFamily  # the family imports models

        return DamperFamily().solver(recording)

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
