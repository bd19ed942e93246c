"""Synthetic structural tests that conceal missing physics, with a known truth.

The structural family's diagnosis names what a Bouc-Wen restoring force F (kN) under
an imposed displacement x (mm) leaves out of a quasi-static cyclic test of a column,
wall or connection. It has to be proven on records where an effect is *concealed* (it
changes the force by only a few noise sigmas) and on clean records, where nothing may
be named. This module makes such records, in the style of `_synthetic.py` (the piezo
family's suite).

The truth is deliberately *not* written in the diagnosis catalogue's equations
(`StructuralBoucWen`: Baber-Wen nu, eta linear in the hysteretic energy; Foliente's
BWBN pinching whose depth grows with that energy; gamma + skew*sign(z) and a
|x| stiffness skew; a Legendre drift), because real tests never follow them:

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

Loading protocols (`loading_protocol`) imitate real tests: "cyclic", stepwise growing
amplitudes with 2-3 cycles per level (ATC-24 / FEMA 461), and "earthquake", the
turning points of an enveloped random-phase band-limited displacement (a
quasi-static earthquake-like history). Each excursion is sampled as a test controller
does, with nearly uniform displacement increments, turning points exactly on samples.
There is no real time: the record's time is the pseudo time t = sample index (dt = 1,
`time_unit` "sample"); the models are rate independent, so only the order matters.

Each effect's size is *set*: its coefficient is rescaled (exactly where the force is
linear in it, by the safeguarded secant search of `_synthetic` where it is not) until
the RMS of (F with the effect - F without it) equals the requested number of noise
sigmas.
"""

import math
from collections.abc import Callable, Mapping
from typing import ClassVar, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, PRNGKeyArray

from ._inputs import InputPath
from ._models.base import AbstractHysteresisModel, BoucWenShape, as_parameter
from ._models.bouc_wen import BoucWen
from ._recording import Recording
from ._signals import _check
from ._simulate import RK4, simulate
from ._smoothing import AbstractSmoothing
from ._synthetic import _loguniform, _rms, _rng, _solve_size, _validate_sizes


EFFECTS: tuple[str, ...] = ("degradation", "pinching", "asymmetry", "drift")
FORMS: dict[str, tuple[str, ...]] = {
    "degradation": ("ductility", "energy"),
    "pinching": ("slip", "baber_noori"),
    "asymmetry": ("yield", "hardening"),
    "drift": ("load_cell",),
}
NOISE_KINDS: tuple[str, ...] = ("white", "coloured")
PROTOCOLS: tuple[str, ...] = ("cyclic", "earthquake")

_DEFAULT_SIZES = (4.0, 12.0)  # noise sigmas, when size_sigmas is None
_POINTS = (500, 20000)  # the accepted range of `points`
_REACHED = 0.98  # a form that reaches less than this share of the target gives way


# ------------------------------------------------------------------ truth forms


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


# --------------------------------------------------------------- the protocols


def _sample_excursions(vertices: np.ndarray, points: int) -> np.ndarray:
    """`points` samples along the piecewise-linear path through `vertices` (its
    turning points): every excursion gets a whole number of equal steps, in
    proportion to its length (at least one), so the increments are nearly uniform
    and every turning point is a sample."""
    vertices = np.asarray(vertices, dtype=float)
    keep = np.concatenate([[True], np.abs(np.diff(vertices)) > 0])
    vertices = vertices[keep]
    lengths = np.abs(np.diff(vertices))
    steps = points - 1
    if lengths.size > steps:
        raise ValueError(
            f"the protocol has {lengths.size} excursions but only {steps} steps; "
            "ask for more points."
        )
    raw = lengths / lengths.sum() * steps
    counts = np.maximum(np.floor(raw).astype(int), 1)
    while counts.sum() < steps:  # largest remainders first
        counts[np.argmax(raw - counts)] += 1
    while counts.sum() > steps:  # the minimum of one step overshot: take from the
        counts[np.argmax(np.where(counts > 1, counts - raw, -np.inf))] -= 1  # longest
    pieces = [vertices[:1]]
    for start, end, count in zip(vertices[:-1], vertices[1:], counts):
        pieces.append(np.linspace(start, end, count + 1)[1:])
    return np.concatenate(pieces)


def _cyclic_vertices(rng: np.random.Generator, x_y: float) -> tuple[np.ndarray, str]:
    levels = int(rng.integers(6, 11))
    cycles = int(rng.choice([2, 3]))
    first, last = rng.uniform(0.2, 0.5), rng.uniform(4.0, 8.0)
    amplitudes = x_y * np.geomspace(first, last, levels)
    sign = float(rng.choice([1.0, -1.0]))
    vertices = [0.0]
    for a in amplitudes:
        vertices += [sign * a, -sign * a] * cycles
    vertices.append(0.0)
    growth = (last / first) ** (1 / (levels - 1))
    what = (
        f"cyclic, {levels} levels x {cycles} cycles from {first:.3g} to {last:.3g} x_y "
        f"(x {growth:.3g} per level), {'push' if sign > 0 else 'pull'} first"
    )
    return np.asarray(vertices), what


def _earthquake_vertices(
    rng: np.random.Generator, x_y: float
) -> tuple[np.ndarray, str]:
    dense = 4096
    tau = np.linspace(0.0, 1.0, dense)
    low = rng.uniform(8.0, 15.0)  # cycles per record
    high = low * rng.uniform(3.0, 5.0)
    components = 40
    f = rng.uniform(low, high, components)
    amplitude = 1.0 / f  # a displacement spectrum falling with frequency
    phase = rng.uniform(0.0, 2 * math.pi, components)
    signal = np.sum(
        amplitude[:, None] * np.sin(2 * math.pi * f[:, None] * tau + phase[:, None]),
        axis=0,
    )
    rise = rng.uniform(0.08, 0.2)
    plateau_end = rise + rng.uniform(0.25, 0.45)
    decay = -math.log(0.03) / (1 - plateau_end)
    envelope = np.where(
        tau < rise,
        (tau / rise) ** 2,
        np.where(tau < plateau_end, 1.0, np.exp(-decay * (tau - plateau_end))),
    )
    x = signal * envelope
    peak = rng.uniform(3.0, 6.0)
    x *= peak * x_y / np.max(np.abs(x))
    slope = np.diff(x)
    turns = np.flatnonzero(np.sign(slope[1:]) != np.sign(slope[:-1])) + 1
    vertices = np.concatenate([[0.0], x[turns], [0.0]])
    what = (
        f"earthquake-like, {components} random-phase components at {low:.3g}-"
        f"{high:.3g} cycles per record, envelope rise {rise:.2f}, strong motion to "
        f"{plateau_end:.2f}, peak {peak:.3g} x_y, {vertices.size - 1} excursions"
    )
    return vertices, what


def loading_protocol(
    key: PRNGKeyArray,
    *,
    yield_displacement: float,
    protocol: str = "cyclic",
    points: int = 2000,
) -> tuple[InputPath, str]:
    """An imposed-displacement history like a real quasi-static test, and a one-line
    description of it. The path's time is the pseudo time t = sample index (t0 = 0,
    dt = 1).

    - "cyclic": 6-10 stepwise growing amplitude levels (x 1.3-1.9 per level, from
      0.2-0.5 to 4-8 times `yield_displacement`) with 2 or 3 full cycles each, push
      or pull first, ending at zero (ATC-24 / FEMA 461 protocols);
    - "earthquake": the turning points of an enveloped random-phase band-limited
      displacement (40 components over a 3-5 x band of 8-75 cycles per record,
      amplitudes ~1/f; quadratic rise, strong-motion plateau, exponential decay),
      peaking at 3-6 times `yield_displacement`, ending at zero.

    Each excursion between turning points is sampled with equal steps, the steps of
    all excursions as nearly equal as whole numbers allow, as a test controller does.
    """
    owner = "loading_protocol"
    rng = _rng(key, owner)
    _check_points(owner, points)
    protocol = _check_protocol(owner, protocol)
    if not (
        isinstance(yield_displacement, (int, float, np.number))
        and yield_displacement > 0
        and math.isfinite(yield_displacement)
    ):
        raise ValueError(
            f"{owner}(yield_displacement={yield_displacement!r}): pass the yield "
            "displacement, a positive number (mm)."
        )
    build = _cyclic_vertices if protocol == "cyclic" else _earthquake_vertices
    vertices, what = build(rng, float(yield_displacement))
    x = _sample_excursions(vertices, points)
    return InputPath(0.0, 1.0, jnp.asarray(x)), what


# ----------------------------------------------------------- sizing the effects


def _truth_solver(x: np.ndarray, x_y: float) -> RK4:
    """RK4 steps of at most 2 % of the yield displacement (the pinching and slip
    windows are 10-35 % of it wide), substeps rounded up to a power of two so that
    records of one length share few compilations."""
    largest = float(np.max(np.abs(np.diff(x))))
    need = max(2, math.ceil(largest / (0.02 * x_y)))
    return RK4(substeps=min(2 ** math.ceil(math.log2(need)), 64))


@eqx.filter_jit
def _run_jit(model: StructuralTruth, path: InputPath, solver: RK4):
    return simulate(model, path, solver, return_state=True)


def _run(model: StructuralTruth, path: InputPath, solver: RK4):
    """(force, states) under one compilation per record shape and substeps."""
    force, states = _run_jit(model.astype(path.values.dtype), path, solver)
    return np.asarray(force), np.asarray(states)


class _Context(NamedTuple):
    x: np.ndarray
    x_y: float
    k: float
    alpha: float
    energy: float  # the cumulative loading work at the end of the base record
    duration: float
    measure: Callable  # (field name, component) -> RMS of the change it makes


# A sizer returns (field, component, RMS reached, form, description).
_Sized = tuple[str, eqx.Module, float, str, str]


def _first_reaching(target: float, forms: list[Callable[[], _Sized]]) -> _Sized:
    """The first form that reaches the target size, else the one that came closest
    (a form is capped where its physics would turn unrealistic)."""
    best = forms[0]()
    for form in forms[1:]:
        if best[2] >= _REACHED * target:
            break
        sized = form()
        best = sized if sized[2] > best[2] else best
    return best


def _in_order(rng: np.random.Generator, forms: list) -> list:
    """The forms with a random first choice, the others as fallbacks."""
    first = int(rng.integers(len(forms)))
    return forms[first:] + forms[:first]


def _size_degradation(rng, ctx: _Context, target: float) -> _Sized:
    def ductility():
        mode = str(rng.choice(["strength", "stiffness", "both"]))
        ratio = {"strength": (1.0, 0.0), "stiffness": (0.0, 1.0)}.get(
            mode, (1.0, rng.uniform(1.0, 4.0))
        )
        make = lambda p: DuctilityDegradation(p * ratio[0], p * ratio[1])
        p, r = _solve_size(
            lambda p: ctx.measure("ductility_degradation", make(p)),
            target,
            0.05,
            linear=False,
            most=1.0 / max(ratio),
        )
        d = make(p)
        what = (
            f"ductility-driven ({mode}): yield level / (1 + "
            f"{float(d.strength):.4g}*(mu - 1)+), elastic slope * "
            f"mu^-{float(d.stiffness):.4g}"
        )
        return "ductility_degradation", d, r, "ductility", what

    def energy():
        mode = str(rng.choice(["yield", "damage"]))
        make = lambda p: (
            EnergyDegradation(yield_rate=p)
            if mode == "yield"
            else EnergyDegradation(damage_rate=p)
        )
        # Capped where the last sample keeps 10 % of the strength.
        p, r = _solve_size(
            lambda p: ctx.measure("energy_degradation", make(p)),
            target,
            0.1 / ctx.energy,
            linear=False,
            most=math.log(10.0) / ctx.energy,
        )
        on = "the yield force" if mode == "yield" else "the hysteretic force (damage)"
        what = (
            f"energy-driven: {on} * exp(-{p:.4g}*e), e the loading work in F_y*x_y "
            f"({ctx.energy:.4g} at the end)"
        )
        return "energy_degradation", make(p), r, "energy", what

    return _first_reaching(target, _in_order(rng, [ductility, energy]))


def _size_pinching(rng, ctx: _Context, target: float) -> _Sized:
    def slip():
        share, window = rng.uniform(0.85, 0.95), rng.uniform(0.1, 0.3)
        make = lambda p: SlipGap(p, share, window)
        p, r = _solve_size(
            lambda p: ctx.measure("slip", make(p)), target, 0.3, linear=False, most=2.0
        )
        what = (
            f"slip gap: half-width {p:.4g}*(max|x| - x_y)+, {share:.3g} of dx slips "
            f"while |F| < ~{window:.3g} F_y"
        )
        return "slip", make(p), r, "slip", what

    def baber_noori():
        rate, width = rng.uniform(0.5, 2.0), rng.uniform(0.15, 0.35)
        shift = rng.uniform(0.0, 0.15)
        make = lambda p: DuctilityPinching(p, rate, width, shift)
        p, r = _solve_size(
            lambda p: ctx.measure("pinching", make(p)),
            target,
            0.3,
            linear=False,
            most=0.95,
        )
        what = (
            f"Baber-Noori slip-lock: zeta1 = {p:.4g}*(1 - exp(-{rate:.3g}*(mu - 1)+)), "
            f"width {width:.3g} zu, shift {shift:.3g} zu"
        )
        return "pinching", make(p), r, "baber_noori", what

    return _first_reaching(target, _in_order(rng, [slip, baber_noori]))


def _size_asymmetry(rng, ctx: _Context, target: float) -> _Sized:
    def side_yield():
        sign = float(rng.choice([-1.0, 1.0]))
        make = lambda p: SideYield(sign * p)
        p, r = _solve_size(
            lambda p: ctx.measure("side_yield", make(p)),
            target,
            0.1,
            linear=False,
            most=0.6,
        )
        what = (
            f"side-dependent yield level zu*(1 + {sign * p:.4g}*sign(z)) "
            f"({'push' if sign > 0 else 'pull'} stronger)"
        )
        return "side_yield", make(p), r, "yield", what

    def hardening():
        direction = float(rng.choice([-1.0, 1.0]))
        reach = float(np.max(direction * ctx.x))
        onset = min(rng.uniform(0.5, 1.5) * ctx.x_y, 0.6 * reach)
        make = lambda p: OneSidedHardening(p, onset, direction)
        p, r = _solve_size(
            lambda p: ctx.measure("hardening", make(p)),
            target,
            ctx.alpha * ctx.k,
            linear=True,
        )
        what = (
            f"one-sided hardening {p:.4g} kN/mm ({p / (ctx.alpha * ctx.k):.3g} x the "
            f"post-yield stiffness) in {'push' if direction > 0 else 'pull'} beyond "
            f"{onset:.4g} mm"
        )
        return "hardening", make(p), r, "hardening", what

    return _first_reaching(target, _in_order(rng, [side_yield, hardening]))


def _size_drift(rng, ctx: _Context, target: float) -> _Sized:
    num = ctx.x.shape[0]
    offset = rng.uniform(0.2, 1.0) * rng.choice([-1.0, 1.0])
    trend = rng.uniform(0.2, 1.0) * rng.choice([-1.0, 1.0])
    walk = np.cumsum(rng.standard_normal(num))
    width = max(3, num // 25)
    smooth = np.convolve(
        np.pad(walk, width, mode="edge"), np.ones(width) / width, mode="same"
    )[width:-width]
    smooth -= smooth[0]
    wander = rng.uniform(0.3, 1.0) * smooth / max(_rms(smooth - smooth.mean()), 1e-30)
    make = lambda p: LoadCellDrift(p, offset, trend, wander, ctx.duration)
    p, r = _solve_size(
        lambda p: ctx.measure("drift", make(p)), target, 1.0, linear=True
    )
    what = (
        f"load cell {p:.4g} kN*({offset:.3g} + {trend:.3g}*t/T + wander), wander a "
        f"smoothed random walk of rms {_rms(wander - wander.mean()):.3g}"
    )
    return "drift", make(p), r, "load_cell", what


_SIZERS = {
    "degradation": _size_degradation,
    "pinching": _size_pinching,
    "asymmetry": _size_asymmetry,
    "drift": _size_drift,
}


# ----------------------------------------------------------------------- noise


def _noise(
    rng: np.random.Generator, kind: str, sigma: float, num: int
) -> tuple[np.ndarray, str]:
    white = rng.standard_normal(num)
    if kind == "white":
        return sigma * white, "white Gaussian"
    rho = rng.uniform(0.6, 0.9)
    drive = np.sqrt(1 - rho**2) * white
    drive[0] = white[0]  # start in the stationary distribution
    import scipy.signal  # deferred: heavy import, needed only here

    ar = np.asarray(scipy.signal.lfilter([1.0], [1.0, -rho], drive))
    return sigma * ar, f"coloured AR(1), coefficient {rho:.3g}"


# ------------------------------------------------------------------ the cases


class StructuralCase(eqx.Module):
    """A synthetic structural test and the truth behind it.

    - `recording`: the noisy record (u the displacement in mm, y the force in kN, t
      the pseudo time: the sample index, `time_unit` "sample");
    - `effects`: the concealed effects, in catalogue order (empty: a clean record);
    - `sigma`: the noise's marginal standard deviation (kN);
    - `sizes`: per effect, the RMS of (F with that effect alone - F without it) in
      units of `sigma`;
    - `forms`: per effect, the truth form used (see `FORMS`);
    - `truth_description`: the base, the protocol, each effect's form and
      coefficients, and the noise;
    - `truth`: the `StructuralTruth` that made the noise-free force, `base` the
      Bouc-Wen model under it (what a perfect diagnosis recovers), `noiseless` that
      force, `noise` the noise kind, `protocol` the loading protocol, `solver` the
      integrator used.
    """

    recording: Recording
    effects: tuple[str, ...]
    sigma: float
    sizes: dict[str, float]
    forms: dict[str, str]
    truth_description: str
    truth: StructuralTruth
    base: BoucWen
    noiseless: np.ndarray
    noise: str
    protocol: str
    solver: RK4


def _check_points(owner: str, points) -> None:
    if isinstance(points, bool) or not isinstance(points, (int, np.integer)):
        raise TypeError(
            f"{owner}: points must be an integer number of samples, e.g. points=2000, "
            f"got {points!r}."
        )
    if not _POINTS[0] <= points <= _POINTS[1]:
        raise ValueError(
            f"{owner}(points={points}): points must be between {_POINTS[0]} and "
            f"{_POINTS[1]}; real cyclic tests have 1000-4000."
        )


def _check_protocol(owner: str, protocol) -> str:
    if protocol == "earthquake-like":
        protocol = "earthquake"
    if protocol not in PROTOCOLS:
        raise ValueError(
            f"{owner}(protocol={protocol!r}): protocol must be one of "
            f"{', '.join(PROTOCOLS)}."
        )
    return protocol


def _validate_effects(effects, owner: str) -> tuple[str, ...]:
    if isinstance(effects, str):
        raise TypeError(
            f"{owner}: effects must be a tuple of effect names, e.g. ({effects!r},), "
            "not a string."
        )
    try:
        effects = tuple(effects)
    except TypeError:
        raise TypeError(
            f"{owner}: effects must be a tuple of effect names, got "
            f"{type(effects).__name__}; pass e.g. ('pinching',) or () for a clean "
            "record."
        ) from None
    unknown = [e for e in effects if e not in EFFECTS]
    if unknown:
        raise ValueError(
            f"{owner}: unknown effect(s) {unknown}; valid names are "
            f"{', '.join(EFFECTS)} (an empty tuple gives a clean recording)."
        )
    if len(set(effects)) != len(effects):
        raise ValueError(f"{owner}: effects {effects} name an effect twice.")
    return tuple(e for e in EFFECTS if e in effects)


def structural_recording(
    effects: tuple[str, ...],
    *,
    key: PRNGKeyArray,
    noise: str = "white",
    protocol: str = "cyclic",
    points: int = 2000,
    size_sigmas: float | Mapping[str, float] | None = None,
) -> StructuralCase:
    """A quasi-static test of a structural element (`structural_base_truth`: a
    Bouc-Wen restoring force, x in mm, F in kN) under an imposed-displacement
    `protocol` ("cyclic" or "earthquake", see `loading_protocol`) of `points`
    samples, that conceals `effects` (names from degradation, pinching, asymmetry,
    drift; `()` gives a clean recording), plus load-cell noise.

    Each effect's form differs from the diagnosis catalogue's (`StructuralBoucWen`;
    see the module docstring), two forms per mechanical effect, drawn from the key.
    Its size is set so that the RMS of the change it makes, alone, is `size_sigmas`
    noise sigmas: one number for all, a mapping per effect, or None to draw each from
    [4, 12]. Where a form cannot reach the size within its realistic range (e.g. a
    Baber-Noori depth above 0.95) the other form is used; `sizes` reports what was
    reached (within 0.5 % of the request when reached) and `forms` which form.

    `noise` is "white" (Gaussian) or "coloured" (AR(1) with coefficient 0.6-0.9, at
    the same marginal sigma); sigma is 0.6-1.5 % of the base force's peak |F|. The
    recording's time is the pseudo time t = sample index (dt = 1).

    Everything random follows from `key`: the base, the protocol, each effect's form
    and size, and the noise. The same key with different effects gives the same
    base, displacement history and noise, so records differ only by the effects.
    """
    owner = "structural_recording"
    effects = _validate_effects(effects, owner)
    _rng(key, owner)
    if noise == "colored":
        noise = "coloured"
    if noise not in NOISE_KINDS:
        raise ValueError(
            f"{owner}(noise={noise!r}): noise must be one of {', '.join(NOISE_KINDS)}."
        )
    protocol = _check_protocol(owner, protocol)
    _check_points(owner, points)
    sizes_wanted = _validate_sizes(size_sigmas, effects, owner)

    k_base, k_protocol, k_effects, k_sizes, k_noise = jax.random.split(key, 5)
    effect_rng = lambda root, e: _rng(jax.random.fold_in(root, EFFECTS.index(e)), owner)
    if sizes_wanted is None:
        sizes_wanted = {
            e: float(effect_rng(k_sizes, e).uniform(*_DEFAULT_SIZES)) for e in effects
        }

    base = structural_base_truth(k_base)
    quiet = StructuralTruth(base)
    x_y = float(quiet.yield_displacement)
    path, what_protocol = loading_protocol(
        k_protocol, yield_displacement=x_y, protocol=protocol, points=points
    )
    x = np.asarray(path.values)
    solver = _truth_solver(x, x_y)
    y_base, states = _run(quiet, path, solver)
    noise_rng = _rng(k_noise, owner)
    peak = float(np.max(np.abs(y_base)))
    sigma = _loguniform(noise_rng, 0.006, 0.015) * peak

    def measure(field: str, component) -> float:
        model = eqx.tree_at(lambda m: getattr(m, field), quiet, component)
        return _rms(_run(model, path, solver)[0] - y_base)

    ctx = _Context(
        x,
        x_y,
        float(base.k),
        float(base.alpha),
        float(states[-1, 2]),
        float(points - 1),
        measure,
    )
    components, sizes, forms, lines = {}, {}, {}, []
    for effect in effects:
        target = sizes_wanted[effect] * sigma
        field, component, reached, form, what = _SIZERS[effect](
            effect_rng(k_effects, effect), ctx, target
        )
        components[field] = component
        sizes[effect] = reached / sigma
        forms[effect] = form
        lines.append(f"{effect} [{form}]: {what}; size {sizes[effect]:.3g} sigma")

    truth = StructuralTruth(base, **components)
    y_true = _run(truth, path, solver)[0] if effects else y_base
    e, what_noise = _noise(noise_rng, noise, sigma, y_true.shape[0])
    label = "+".join(effects) if effects else "clean"
    recording = Recording(
        np.arange(points, dtype=np.float64),
        x,
        y_true + e,
        name=f"structural-{label}-{protocol}-{noise}",
        input_name="displacement",
        output_name="force",
        input_unit="mm",
        output_unit="kN",
        time_unit="sample",
    )
    p = {k: float(v) for k, v in base.parameters().items()}
    head = (
        f"base: BoucWen(k={p['k']:.5g}, alpha={p['alpha']:.4g}, D=1, A=1, "
        f"beta={p['beta']:.5g}, gamma={p['gamma']:.5g}, n={p['n']:.4g}) [x in mm, F "
        f"in kN]; x_y {x_y:.4g} mm, F_y {float(quiet.yield_force):.4g} kN"
    )
    body = lines or ["no effects (clean recording)"]
    tail = (
        f"noise: {what_noise}, sigma {sigma:.4g} kN ({sigma / peak:.3%} of the peak "
        "force)"
    )
    return StructuralCase(
        recording=recording,
        effects=effects,
        sigma=sigma,
        sizes=sizes,
        forms=forms,
        truth_description="\n".join(
            [head, f"protocol: {what_protocol}, {points} points", *body, tail]
        ),
        truth=truth,
        base=base,
        noiseless=y_true,
        noise=noise,
        protocol=protocol,
        solver=solver,
    )
