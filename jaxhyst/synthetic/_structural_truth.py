"""The structural truth: the model behind a concealed structural test, its base,
and the truth forms of each effect.

The structural family's diagnosis names what a Bouc-Wen restoring force F (kN) under
an imposed displacement x (mm) leaves out of a quasi-static cyclic test of a column,
wall or connection. It has to be proven on records where an effect is *concealed* (it
changes the force by only a few noise sigmas) and on clean records, where nothing may
be named. This subpackage makes such records, in the style of the piezo family's
suite (`concealed_recording`).

The truth is deliberately *not* written in the diagnosis catalogue's equations
(`StructuralBoucWen`: Baber-Wen nu, eta linear in the hysteretic energy; Foliente's
BWBN pinching whose depth grows with that energy; the shape term times
1 + yield_skew*sign(z) and a |x| stiffness skew; a Legendre drift), because real
tests never follow them:

===========  ===============================================================
effect       truth form (one per record, chosen by the key; name in `forms`)
===========  ===============================================================
degradation  "ductility" `DuctilityDegradation`: driven by the largest past
             ductility mu = max|x|/x_y: the yield level falls as
             1/(1 + strength*(mu - 1)+), the elastic slope of the hysteretic
             element as mu^-stiffness (Takeda-like); strength, stiffness or
             both. "energy" `EnergyDegradation`: exponential in the
             cumulative loading work e (in units of F_y*x_y), on the yield
             force directly, zu*exp(-rate*e) (strength), or on the whole
             hysteretic force, *exp(-rate*e) (continuum damage: strength and
             stiffness together)
pinching     "slip" `SlipGap`: a slip displacement in series with the element,
             which the element does not see: a share of dx goes into slip while
             |F| is near zero (within ~window*F_y), inside a gap whose
             half-width grows with the plastic excursion, growth*(max|x| - x_y)
             (bolt-hole ovalisation, crack opening, dowel embedment).
             "baber_noori" `DuctilityPinching`: a Baber-Noori slip-lock
             zdot *= 1 - zeta1*exp(-((z*sign(xdot) - q*zu)/(w*zu))^2) whose
             depth grows with the largest past ductility,
             zeta1 = depth*(1 - exp(-rate*(mu - 1)+)), at a fixed width
asymmetry    "yield" `SideYield`: the yield level differs in push and pull,
             zu*(1 + split*sign(z)). "hardening" `OneSidedHardening`: an extra
             post-yield stiffness beyond an onset displacement on one side only
             (a tie or a flange that works in one direction)
drift        "load_cell" `LoadCellDrift`: a load-cell offset plus a linear trend
             plus a slow random wander (a smoothed random walk), independent of
             the mechanics
===========  ===============================================================
"""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float, PRNGKeyArray

from .._models.base import AbstractHysteresisModel, BoucWenShape, as_parameter
from .._models.bouc_wen import BoucWen
from .._signals import _check
from .._smoothing import AbstractSmoothing
from ._random import _loguniform, _rng


STRUCTURAL_FORMS: dict[str, tuple[str, ...]] = {
    "degradation": ("ductility", "energy"),
    "pinching": ("slip", "baber_noori"),
    "asymmetry": ("yield", "hardening"),
    "drift": ("load_cell",),
}


class DuctilityDegradation(eqx.Module):
    """degradation, driven by the largest past ductility mu = max|x| / x_y
    (excess = (mu - 1)+): the hysteretic element's yield level is divided by
    1 + strength*excess and its elastic slope by (1 + excess)^stiffness. Both only
    fall when the test reaches a new peak. Zero coefficients are off."""

    strength: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    stiffness: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)

    def __check_init__(self):
        _check("DuctilityDegradation", "strength", self.strength, "non-negative")
        _check("DuctilityDegradation", "stiffness", self.stiffness, "non-negative")

    def level(self, excess):
        return 1 / (1 + self.strength * excess)

    def slope(self, excess):
        return jnp.power(1 + excess, -self.stiffness)


class EnergyDegradation(eqx.Module):
    """degradation, exponential in the cumulative loading work e (the work the
    hysteretic force does while |z| grows, in units of F_y*x_y): the yield level is
    multiplied by exp(-yield_rate*e), and the whole hysteretic force by
    exp(-damage_rate*e) (continuum damage). Zero rates are off."""

    yield_rate: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    damage_rate: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)

    def __check_init__(self):
        _check("EnergyDegradation", "yield_rate", self.yield_rate, "non-negative")
        _check("EnergyDegradation", "damage_rate", self.damage_rate, "non-negative")

    def level(self, energy):
        return jnp.exp(-self.yield_rate * energy)

    def damage(self, energy):
        return jnp.exp(-self.damage_rate * energy)


class SlipGap(eqx.Module):
    """pinching as a slip element in series: the hysteretic element sees x - s, and
    the slip s moves by share*dx while the force is near zero,

        sdot = share * exp(-(F/(window*F_y))^2) * room * xdot,

    inside a gap |s| <= G = growth*(max|x| - x_y)+ that opens with the plastic
    excursion; `room` falls from 1 to 0 over the last quarter of the gap ahead.
    `growth = 0` is off (the gap stays shut)."""

    growth: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    share: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.9)
    window: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.2)

    def __check_init__(self):
        _check("SlipGap", "growth", self.growth, "non-negative")
        _check("SlipGap", "window", self.window, "positive", "pass a share of F_y.")

    def rate(self, slip, force, xdot, excess, zu, fy, smoothing: AbstractSmoothing):
        gap = self.growth * zu * excess
        near_zero = jnp.exp(-jnp.square(force / (self.window * fy)))
        ahead = gap - slip * smoothing.sign(xdot)
        room = jnp.clip(ahead / jnp.maximum(0.25 * gap, 1e-9 * zu), 0.0, 1.0)
        return self.share * near_zero * room * xdot


class DuctilityPinching(eqx.Module):
    """pinching as a Baber-Noori slip-lock whose depth grows with the largest past
    ductility (not with energy):

        zdot *= 1 - zeta1*exp(-((z*sign(xdot) - shift*zu)/(width*zu))^2),
        zeta1 = depth*(1 - exp(-rate*excess)).

    `depth = 0` is off."""

    depth: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    rate: Float[Array, ""] = eqx.field(converter=as_parameter, default=1.0)
    width: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.25)
    shift: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.1)

    def __check_init__(self):
        _check(
            "DuctilityPinching", "width", self.width, "positive", "pass a share of zu."
        )

    def factor(self, z, xdot, excess, zu, smoothing: AbstractSmoothing):
        zeta1 = self.depth * -jnp.expm1(-self.rate * excess)
        distance = (z * smoothing.sign(xdot) - self.shift * zu) / (self.width * zu)
        return 1 - zeta1 * jnp.exp(-jnp.square(distance))


class SideYield(eqx.Module):
    """asymmetry: the yield level differs in push and pull, zu -> zu*(1 +
    split*sign(z)). `split = 0` is off; |split| < 1."""

    split: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)

    def level(self, z, smoothing: AbstractSmoothing):
        return 1 + self.split * smoothing.sign(z)


class OneSidedHardening(eqx.Module):
    """asymmetry: a parallel spring that works on one side beyond an onset,

        F += stiffness * direction * (direction*x - onset)+,

    so the post-yield stiffness differs in push (direction = +1) and pull (-1).
    `stiffness = 0` is off."""

    stiffness: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    onset: Float[Array, ""] = eqx.field(converter=as_parameter, default=1.0)
    direction: Float[Array, ""] = eqx.field(converter=as_parameter, default=1.0)

    def __check_init__(self):
        _check("OneSidedHardening", "onset", self.onset, "positive", "pass mm.")

    def force(self, x):
        return (
            self.stiffness
            * self.direction
            * jnp.maximum(self.direction * x - self.onset, 0.0)
        )


class LoadCellDrift(eqx.Module):
    """drift, independent of the mechanics: a load-cell offset, a linear trend and a
    slow wander (sampled on `duration`'s grid, linearly interpolated),

        d(t) = scale * (offset + trend*t/duration + wander(t)).

    `scale = 0` is off."""

    scale: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    offset: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    trend: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    wander: Float[Array, " m"] = eqx.field(converter=as_parameter, default=(0.0, 0.0))
    duration: Float[Array, ""] = eqx.field(converter=as_parameter, default=1.0)

    def __check_init__(self):
        _check("LoadCellDrift", "duration", self.duration, "positive")
        if self.wander.ndim != 1 or self.wander.shape[0] < 2:
            raise ValueError(
                f"LoadCellDrift: wander must be a 1-D array of at least 2 samples, "
                f"got shape {self.wander.shape}."
            )

    def __call__(self, t):
        grid = jnp.linspace(0.0, self.duration, self.wander.shape[0])
        wander = jnp.interp(t, grid, self.wander)
        return self.scale * (self.offset + self.trend * t / self.duration + wander)


class StructuralTruth(AbstractHysteresisModel):
    """The model that generates a concealed structural test: the Bouc-Wen restoring
    force `base` (eq. 1-2) with every truth form of this module built in and off by
    default (then it is exactly `base`):

        mu, excess = max|x| / zu, (mu - 1)+               (zu = x_y, the yield level)
        sdot   = SlipGap(F, s, xdot)                      (pinching, slip)
        ve     = xdot - sdot                              (what the element sees)
        level  = DuctilityDegradation.level * EnergyDegradation.level * SideYield
        zdot   = DuctilityPinching * (A - (beta*sign(ve)*sign(z) + gamma)*|z/level|^n)
                 * ve * DuctilityDegradation.slope / D
        edot   = (1 - alpha)*D*k*(z*ve)+ / (F_y*x_y)     (cumulative loading work)
        F      = alpha*k*(x - s) + OneSidedHardening(x)
                 + (1 - alpha)*D*k*z*EnergyDegradation.damage + LoadCellDrift(t)

    State (4): z, the largest |x| so far (updated exactly once per sample by
    `sample_update`; inside a sample interval max(state, |x|) is used, exact for a
    piecewise-linear input), e, and the slip s. Its `parameters()` are the base's;
    the effects' coefficients live in the effect fields. Simulate it with
    `simulate(truth, path, RK4(substeps=...))`.
    """

    base: BoucWen
    ductility_degradation: DuctilityDegradation = eqx.field(
        default_factory=DuctilityDegradation
    )
    energy_degradation: EnergyDegradation = eqx.field(default_factory=EnergyDegradation)
    slip: SlipGap = eqx.field(default_factory=SlipGap)
    pinching: DuctilityPinching = eqx.field(default_factory=DuctilityPinching)
    side_yield: SideYield = eqx.field(default_factory=SideYield)
    hardening: OneSidedHardening = eqx.field(default_factory=OneSidedHardening)
    drift: LoadCellDrift = eqx.field(default_factory=LoadCellDrift)

    parameter_names: ClassVar[tuple[str, ...]] = BoucWen.parameter_names
    state_size: ClassVar[int] = 4

    @property
    def smoothing(self) -> AbstractSmoothing:
        return self.base.smoothing

    # The base parameters, so that `parameters()` and `replace()` read the
    # underlying Bouc-Wen model.
    @property
    def k(self):
        return self.base.k

    @property
    def alpha(self):
        return self.base.alpha

    @property
    def D(self):
        return self.base.D

    @property
    def A(self):
        return self.base.A

    @property
    def beta(self):
        return self.base.beta

    @property
    def gamma(self):
        return self.base.gamma

    @property
    def n(self):
        return self.base.n

    def bouc_wen_shape(self) -> BoucWenShape:
        """The base model's shape (what `bibo_stability` checks)."""
        return self.base.bouc_wen_shape()

    @property
    def yield_displacement(self) -> Float[Array, ""]:
        """zu = (A/(beta + gamma))^(1/n): where z saturates (x_y)."""
        b = self.base
        return jnp.power(b.A / (b.beta + b.gamma), 1 / b.n)

    @property
    def yield_force(self) -> Float[Array, ""]:
        """F_y = (1 - alpha)*D*k*zu: the hysteretic force's saturation level."""
        b = self.base
        return (1 - b.alpha) * b.D * b.k * self.yield_displacement

    def _force(self, x, state):
        """The force the specimen transmits (without the load-cell drift)."""
        b = self.base
        z, energy, slip = state[0], state[2], state[3]
        hysteretic = (1 - b.alpha) * b.D * b.k * z
        return (
            b.alpha * b.k * (x - slip)
            + self.hardening.force(x)
            + hysteretic * self.energy_degradation.damage(energy)
        )

    def vector_field(self, t, state, drive):
        b, s = self.base, self.smoothing
        x, xdot = drive.u, drive.udot
        z, peak, energy, slip = state[0], state[1], state[2], state[3]
        zu, fy = self.yield_displacement, self.yield_force
        excess = jnp.maximum(jnp.maximum(peak, jnp.abs(x)) / zu - 1, 0.0)
        force = self._force(x, state)
        slip_dot = self.slip.rate(slip, force, xdot, excess, zu, fy, s)
        ve = xdot - slip_dot
        level = (
            self.ductility_degradation.level(excess)
            * self.energy_degradation.level(energy)
            * self.side_yield.level(z, s)
        )
        shape = (b.beta * s.sign(ve) * s.sign(z) + b.gamma) * s.abs_pow(z / level, b.n)
        pinching = self.pinching.factor(z, ve, excess, zu, s)
        slope = self.ductility_degradation.slope(excess)
        zdot = pinching * (b.A - shape) * ve * slope / b.D
        work = (1 - b.alpha) * b.D * b.k * jnp.maximum(z * ve, 0.0)
        energy_dot = work / (fy * zu)
        return jnp.stack([zdot, jnp.zeros_like(zdot), energy_dot, slip_dot])

    def output(self, t, state, drive):
        return self._force(drive.u, state) + self.drift(t)

    def initial_state(self, drive):
        u = jnp.asarray(drive.u)
        zero = jnp.zeros_like(u)
        return jnp.stack([zero, jnp.abs(u), zero, zero])

    def sample_update(self, inputs):
        values = inputs.values

        def update(start, end, interval):
            peak = jnp.maximum(start[1], jnp.abs(values[interval + 1]))
            return end.at[1].set(peak)

        return update


# ------------------------------------------------------------------ the base


def structural_base_truth(key: PRNGKeyArray) -> BoucWen:
    """A test-like Bouc-Wen restoring force (eq. 1-2) with x in mm and F in kN, in the
    structural family's gauge D = 1, A = 1 (z is a displacement that saturates at the
    yield displacement x_y = zu), randomised:

    - x_y log-uniform in [4, 15] mm and the hysteretic yield force F_y = (1 - alpha)*
      k*x_y log-uniform in [80, 800] kN (a column, a wall or a connection);
    - post-yield stiffness ratio alpha in [0.02, 0.12];
    - n in [1, 3] (gradual to sharp yielding), beta/(beta + gamma) in [0.5, 0.9]
      (beta >= |gamma|: Table 2's stable class), beta + gamma = x_y^-n.
    """
    rng = _rng(key, "structural_base_truth")
    x_y = _loguniform(rng, 4.0, 15.0)
    f_y = _loguniform(rng, 80.0, 800.0)
    alpha = rng.uniform(0.02, 0.12)
    n = rng.uniform(1.0, 3.0)
    ratio = rng.uniform(0.5, 0.9)
    total = x_y**-n
    k = f_y / ((1 - alpha) * x_y)
    return BoucWen(k, alpha, 1.0, 1.0, ratio * total, (1 - ratio) * total, n)
