"""Concealed MR damper cases: a white-noise characterisation test (random
displacement, random piecewise-constant command, as in Dyke's tests) whose force
hides damper-family effects under load-cell noise, and the truth behind it.

The truth is a Bouc-Wen damper of fixed field (`BoucWenDamper`, N, cm, s, V) with the
damper catalogue's effects written in forms that differ from the diagnosis's own
(`ExtendedDamper`: affine or hyperbolic field, one or two real-pole lag stages,
rigid-spring-free series dashpot, spline drift, gamma skew and sign-switched c0),
because real dampers never follow them:

================  =============================================================
effect            truth form (one per record, chosen by the key; name in `forms`)
================  =============================================================
field_dependence  "exponential": alpha, c0 (and the internal dashpot c1) grow by
                  gain*g(q), g = (1 - exp(-q/q_s))/(1 - exp(-1/q_s)) with q the
                  field over 2.5 V (saturation, q_s 0.3-1). "power": g = q^p,
                  p 0.5-0.8 (the yield stress's sub-linear growth)
driver_lag        "second_order": the field follows the command through
                  w'' = omega^2 (v - w) - 2 zeta omega w' (a current driver with
                  the coil's inductance and the fluid's response; zeta 0.6-1).
                  "rate_limited": w' = clip((v - w)/1 ms, -slew, slew) (a driver
                  whose voltage saturates: ramps of fixed slope)
rolloff           "spencer": Spencer et al.'s internal dashpot c1 and internal
                  spring k_i: ydot = (alpha z + c0 xdot + k_i (x - y))/(c0 + c1),
                  z driven by xdot - ydot, F = c1 ydot + k0 (x - x0) + f0
offset            "warming": the accumulator's preload rises as the damper warms,
                  preload*(1 - exp(-e/e_w)), e the dissipated energy, plus a
                  load-cell zero wandering (a smoothed random walk)
asymmetry         "valving": c0*(1 + d*tanh(xdot/v_0)) (one direction damped more,
                  smoothly). "yield": the yield force differs by side, z's
                  saturation level scaled by 1 + split*sign(z)
================  =============================================================
"""

import math
from collections.abc import Mapping
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, PRNGKeyArray

from .._diagnose._families import DAMPER_EFFECT_NAMES, DamperFamily
from .._diagnose._score import project_off
from .._inputs import InputPath
from .._models.base import (
    AbstractHysteresisModel,
    BoucWenShape,
    as_parameter,
    read_input,
)
from .._models.damper import BoucWenDamper, DamperDrive, read_command
from .._recording import Recording
from .._simulate import RK4, simulate
from .._smoothing import AbstractSmoothing
from ._checks import (
    _check_positive,
    _validate_effects,
    _validate_noise,
    _validate_sizes,
)
from ._noise import _load_cell_noise
from ._random import _loguniform, _rng
from ._size_search import _first_reaching, _in_order, _rms, _Sized, _solve_size


DAMPER_FORMS: dict[str, tuple[str, ...]] = {
    "field_dependence": ("exponential", "power"),
    "driver_lag": ("second_order", "rate_limited"),
    "rolloff": ("spencer",),
    "offset": ("warming",),
    "asymmetry": ("valving", "yield"),
}
# The command's full scale (V): Dyke's tests drive 0 to 2.25-2.5 V.
FULL_SCALE = 2.5
_DEFAULT_SIZES = (4.0, 12.0)  # noise sigmas, when size_sigmas is None


class FieldGrowth(eqx.Module):
    """field_dependence: alpha, c0 and the internal dashpot c1 grow by
    alpha_gain*g(q), damping_gain*g(q) and internal_gain*g(q), q = |w|/FULL_SCALE,
    g = (1 - exp(-q/shape))/(1 - exp(-1/shape)) ("exponential") or q^shape
    ("power"); g(1) = 1."""

    form: str = eqx.field(static=True)
    alpha_gain: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    damping_gain: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    internal_gain: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    shape: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.5)

    def growth(self, w):
        q = jnp.abs(w) / FULL_SCALE
        if self.form == "exponential":
            return -jnp.expm1(-q / self.shape) / -jnp.expm1(-1 / self.shape)
        return jnp.power(jnp.maximum(q, 1e-12), self.shape)


class SecondOrderDriver(eqx.Module):
    """driver_lag: w'' = omega^2 (v - w) - 2 zeta omega w', omega = 1/time."""

    time: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.005)
    zeta: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.8)

    def rates(self, w, rate, v):
        omega = 1 / self.time
        return rate, omega**2 * (v - w) - 2 * self.zeta * omega * rate


class RateLimitedDriver(eqx.Module):
    """driver_lag: w' = clip((v - w)/1 ms, -slew, slew), slew = FULL_SCALE/time
    (`time`: how long a full-scale step takes)."""

    time: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.01)

    def rates(self, w, rate, v):
        slew = FULL_SCALE / self.time
        return jnp.clip((v - w) / 1e-3, -slew, slew), jnp.zeros_like(w)


class InternalDashpot(eqx.Module):
    """rolloff: Spencer et al.'s internal dashpot c1 and spring k_i in the block."""

    c1: Float[Array, ""] = eqx.field(converter=as_parameter, default=1e3)
    spring: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)


class Warming(eqx.Module):
    """offset: F += preload*(1 - exp(-e/energy)) + scale*wander(t), e the energy the
    damper has dissipated (N cm), wander sampled on [0, duration]."""

    preload: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    energy: Float[Array, ""] = eqx.field(converter=as_parameter, default=1.0)
    scale: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    wander: Float[Array, " m"] = eqx.field(converter=as_parameter, default=(0.0, 0.0))
    duration: Float[Array, ""] = eqx.field(converter=as_parameter, default=1.0)

    def __call__(self, t, energy):
        grid = jnp.linspace(0.0, self.duration, self.wander.shape[0])
        drift = self.scale * jnp.interp(t, grid, self.wander)
        return self.preload * -jnp.expm1(-energy / self.energy) + drift


class Valving(eqx.Module):
    """asymmetry: c0*(1 + split*tanh(xdot/velocity))."""

    split: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    velocity: Float[Array, ""] = eqx.field(converter=as_parameter, default=1.0)

    def factor(self, xdot):
        return 1 + self.split * jnp.tanh(xdot / self.velocity)


class SideYield(eqx.Module):
    """asymmetry: z saturates at (1 + split*sign(z)) times its level."""

    split: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)

    def level(self, z, smoothing: AbstractSmoothing):
        return 1 + self.split * smoothing.sign(z)


class DamperTruth(AbstractHysteresisModel):
    """The model behind a concealed damper record: `base` (a `BoucWenDamper` with
    A = 1: z is a displacement saturating at the yield displacement) with every
    truth form of this module built in, each off when None (then it is exactly
    `base`, reading the displacement only):

        w        = v, or the driver's output (`driver`)
        g        = field.growth(w)                          (0 without `field`)
        alpha_v  = alpha*(1 + alpha_gain*g), c0_v = c0*(1 + damping_gain*g)*valving
        ydot     = (alpha_v z + c0_v xdot + k_i (x - y))/(c0_v + c1*(1 + internal_gain*g))
                   (0 without `internal`)
        zdot     = (A - (beta*sign(r)*sign(z) + gamma)*|z/level|^n)*r, r = xdot - ydot
        F        = c1_v*ydot (or alpha_v z + c0_v xdot) + k0 (x - x0) + f0 + warming
        edot     = |F*xdot| (the dissipated power, for `warming`)

    State: (z, y, w, w', e). Simulate it with `RK4(substeps=truth_substeps(...))`.
    """

    base: BoucWenDamper
    field: FieldGrowth | None = None
    driver: SecondOrderDriver | RateLimitedDriver | None = None
    internal: InternalDashpot | None = None
    warming: Warming | None = None
    valving: Valving | None = None
    side: SideYield | None = None

    parameter_names: ClassVar[tuple[str, ...]] = ()
    state_size: ClassVar[int] = 5
    input_names: ClassVar[tuple[str, ...]] = ("displacement", "command")

    @property
    def smoothing(self) -> AbstractSmoothing:
        return self.base.smoothing

    def bouc_wen_shape(self) -> BoucWenShape:
        return self.base.bouc_wen_shape()

    def drive(self, path, t, interval=None, frac=None) -> DamperDrive:
        x, xdot = read_input(path, t, interval, frac)
        v, vdot = read_command(path, t, interval, frac)
        return DamperDrive(x, xdot, v, vdot)

    def _block(self, state, drive: DamperDrive):
        """(force through the block, ydot)."""
        b = self.base
        z, y, w = state[0], state[1], state[2]
        alpha, c0, c1 = b.alpha, b.c0, 1.0
        if self.field is not None:
            g = self.field.growth(drive.v if self.driver is None else w)
            alpha = alpha * (1 + self.field.alpha_gain * g)
            c0 = c0 * (1 + self.field.damping_gain * g)
            c1 = 1 + self.field.internal_gain * g
        if self.valving is not None:
            c0 = c0 * self.valving.factor(drive.udot)
        if self.internal is None:
            return alpha * z + c0 * drive.udot, jnp.zeros_like(z)
        c1 = self.internal.c1 * c1
        inner = alpha * z + c0 * drive.udot + self.internal.spring * (drive.u - y)
        ydot = inner / (c0 + c1)
        return c1 * ydot, ydot

    # The drive is the one this model's `drive` returns.
    def vector_field(self, t, state, drive: DamperDrive):  # pyright: ignore[reportIncompatibleMethodOverride]
        b, s = self.base, self.smoothing
        z = state[0]
        block, ydot = self._block(state, drive)
        relative = drive.udot - ydot
        level = 1.0 if self.side is None else self.side.level(z, s)
        shape = (b.beta * s.sign(relative) * s.sign(z) + b.gamma) * s.abs_pow(
            z / level, b.n
        )
        zdot = (b.A - shape) * relative
        if self.driver is None:
            wdot = rate = jnp.zeros_like(z)
        else:
            wdot, rate = self.driver.rates(state[2], state[3], drive.v)
        force = block + b.k0 * (drive.u - b.x0) + b.f0
        edot = jnp.abs(force * drive.udot)
        return jnp.stack([zdot, ydot, wdot, rate, edot])

    def output(self, t, state, drive: DamperDrive):  # pyright: ignore[reportIncompatibleMethodOverride]
        b = self.base
        block, _ = self._block(state, drive)
        force = block + b.k0 * (drive.u - b.x0) + b.f0
        if self.warming is not None:
            force = force + self.warming(t, state[4])
        return force

    def initial_state(self, drive: DamperDrive):  # pyright: ignore[reportIncompatibleMethodOverride]
        x = jnp.asarray(drive.u)
        zero = jnp.zeros_like(x)
        return jnp.stack([zero, x, jnp.asarray(drive.v, x.dtype), zero, zero])

    def stiffness(self, velocity: float) -> float:
        """An estimate (1/s) of the fastest rate of the state equations at
        velocities up to `velocity` (for the RK4 substeps; concrete values)."""
        b = self.base
        A, beta, gamma, n = (float(p) for p in (b.A, b.beta, b.gamma, b.n))
        z_u = (A / (beta + gamma)) ** (1 / n)
        if self.side is not None:
            z_u *= 1 - abs(float(self.side.split))
        rate = n * (abs(beta) + abs(gamma)) * z_u ** (n - 1) * abs(velocity)
        gain = 1.0 if self.field is None else 1 + abs(float(self.field.alpha_gain))
        if self.internal is not None:
            c0 = float(b.c0)
            rate += A * float(b.alpha) * gain / (c0 + float(self.internal.c1))
        if isinstance(self.driver, SecondOrderDriver):
            rate = max(rate, 2 / float(self.driver.time))
        elif isinstance(self.driver, RateLimitedDriver):
            rate = max(rate, 1e3)
        return rate


# ------------------------------------------------------------------ excitation


def _excitation(
    rng: np.random.Generator, duration: float, rate: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """(t, x in cm, command in V, description): a band-limited random displacement
    (flat spectrum from 0.3 Hz to a random 12-30 Hz, peak 0.5-1.2 cm, as Dyke's
    white-noise tests) and a command held at random levels in [0, 2.5] V for random
    times (exponential, mean 30-100 ms, at least 5 ms), switching within a sample."""
    count = int(round(duration * rate)) + 1
    t = np.arange(count) / rate
    top = rng.uniform(12.0, 30.0)
    peak = rng.uniform(0.5, 1.2)
    spectrum = np.zeros(count // 2 + 1, complex)
    freqs = np.fft.rfftfreq(count, 1 / rate)
    band = (freqs >= 0.3) & (freqs <= top)
    spectrum[band] = np.exp(2j * np.pi * rng.random(int(band.sum())))
    x = np.fft.irfft(spectrum, count)
    x *= peak / np.max(np.abs(x))
    hold = rng.uniform(0.03, 0.1)
    switches = [0.0]
    while switches[-1] < duration:
        switches.append(switches[-1] + max(0.005, rng.exponential(hold)))
    levels = rng.uniform(0.0, FULL_SCALE, len(switches))
    command = levels[np.searchsorted(np.asarray(switches), t, side="right") - 1]
    what = (
        f"displacement: flat-spectrum random 0.3-{top:.3g} Hz, peak {peak:.3g} cm; "
        f"command: random levels in [0, {FULL_SCALE:g}] V held {1e3 * hold:.3g} ms on "
        "average"
    )
    return t, x, command, what


# -------------------------------------------------------------------- the base


def damper_base_truth(
    rng: np.random.Generator, yield_floor: float
) -> tuple[BoucWenDamper, str]:
    """A Dyke-like damper of fixed field at zero command (N, cm, s), A = 1: c0
    15-40 N s/cm, k0 3-30 N/cm (the accumulator), f0 within +-50 N, a yield force
    of 100-250 N at a yield displacement log-uniform between 3 `yield_floor` (what
    the damper diagnosis resolves) and 0.05 cm, n in [1, 2], beta/(beta + gamma) in
    [0.5, 0.9]."""
    c0 = rng.uniform(15.0, 40.0)
    k0 = rng.uniform(3.0, 30.0)
    f0 = rng.uniform(-50.0, 50.0)
    force = rng.uniform(100.0, 250.0)
    z_y = _loguniform(rng, min(3 * yield_floor, 0.02), 0.05)
    n = rng.uniform(1.0, 2.0)
    ratio = rng.uniform(0.5, 0.9)
    total = z_y**-n
    base = BoucWenDamper(
        c0, k0, 0.0, force / z_y, f0, 1.0, ratio * total, (1 - ratio) * total, n
    )
    what = (
        f"base: BoucWenDamper(c0={c0:.4g} N s/cm, k0={k0:.4g} N/cm, x0=0, "
        f"alpha={force / z_y:.5g} N/cm, f0={f0:.4g} N, A=1, beta={ratio * total:.5g}, "
        f"gamma={(1 - ratio) * total:.5g}, n={n:.4g}): yield force {force:.4g} N at "
        f"{z_y:.3g} cm"
    )
    return base, what


# ----------------------------------------------------------------------- cases


class DamperCase(eqx.Module):
    """A synthetic MR damper test and the truth behind it.

    - `recording`: the noisy record (u the displacement in cm, more input "command"
      in V, y the force in N, t in s);
    - `effects`: the concealed effects, in catalogue order (empty: a clean record);
    - `sigma`: the noise's marginal standard deviation (N);
    - `sizes`: per effect, the RMS change it makes in units of `sigma`, less what
      a refit of the base takes up to first order (alone; driver_lag: on top of
      the field dependence it lags);
    - `forms`: per effect, the truth form used (see `DAMPER_FORMS`);
    - `truth_description`: the base, the excitation, each effect's form and
      coefficients, and the noise;
    - `truth`: the `DamperTruth` that made the noise-free force, `base` the
      `BoucWenDamper` under it, `noiseless` that force, `noise` the noise kind,
      `solver` the integrator used.
    """

    recording: Recording
    effects: tuple[str, ...]
    sigma: float
    sizes: dict[str, float]
    forms: dict[str, str]
    truth_description: str
    truth: DamperTruth
    base: BoucWenDamper
    noiseless: np.ndarray
    noise: str
    solver: RK4


@eqx.filter_jit
def _run_jit(model: DamperTruth, path: InputPath, solver: RK4):
    return simulate(model, path, solver)


def _truth_substeps(truth: DamperTruth, path: InputPath) -> int:
    """RK4 substeps at one stiffness-times-step per substep (a quarter of RK4's
    stability limit: the truth is a reference), rounded up to a power of two."""
    x = np.asarray(path.values)
    velocity = float(np.max(np.abs(np.diff(x)))) / float(path.dt)
    need = max(1, math.ceil(truth.stiffness(velocity) * float(path.dt)))
    return min(2 ** math.ceil(math.log2(need)), 64)


def damper_recording(
    effects: tuple[str, ...],
    *,
    key: PRNGKeyArray,
    duration: float = 5.0,
    rate: float = 3004.8,
    noise: str = "white",
    size_sigmas: float | Mapping[str, float] | None = None,
) -> DamperCase:
    """A white-noise characterisation test of an MR damper (`duration` s sampled at
    `rate` Hz; default Dyke's 3004.8 Hz) that conceals `effects` (the damper
    catalogue's names, `jh.families.DAMPER_EFFECT_NAMES`: field_dependence,
    driver_lag, rolloff, offset, asymmetry; `()` gives a clean record: a damper that
    ignores its command), plus load-cell noise.

    Each effect's form differs from the diagnosis catalogue's (`ExtendedDamper`;
    see `DamperTruth` and `DAMPER_FORMS`), drawn from the key. Its size is set so
    that the RMS of the change it makes, less the part a refit of the base's
    parameters takes up to first order (the change's least-squares projection on
    the base's output sensitivities), is `size_sigmas` noise sigmas: one number
    for all, a mapping per effect, or None to draw each from [4, 12]; `sizes`
    reports what was reached. (A stiff internal dashpot changes the force by
    several sigmas, almost all of it a smaller c0 and alpha: measured on the raw
    change, such a record was a clean one in disguise.) driver_lag needs
    field_dependence (a lag of a command the force does not follow changes
    nothing); its size is measured on top of it,
    and its time constant is capped at 30 ms (second order) or a full-scale ramp of
    50 ms (rate limited), beyond published drivers: a small field dependence leaves
    its lag below the size asked for.

    `noise` is "white" (Gaussian) or "coloured" (AR(1), coefficient 0.6-0.9, same
    marginal sigma); sigma is 0.5-1.5 % of the base force's peak |F|. Everything
    random follows from `key`; the same key with other effects gives the same base,
    excitation and noise.
    """
    owner = "damper_recording"
    effects = _validate_effects(effects, DAMPER_EFFECT_NAMES, owner)
    _rng(key, owner)
    noise = _validate_noise(noise, owner)
    _check_positive(owner, "duration", duration)
    _check_positive(owner, "rate", rate)
    if duration * rate < 600:
        raise ValueError(
            f"{owner}(duration={duration}, rate={rate}): {duration * rate:.0f} "
            "samples; the damper diagnosis needs at least 600: record longer or "
            "faster."
        )
    if "driver_lag" in effects and "field_dependence" not in effects:
        raise ValueError(
            f"{owner}: driver_lag needs field_dependence (the force of a damper that "
            "ignores its command cannot show the field's lag); pass "
            "('field_dependence', 'driver_lag')."
        )
    sizes_wanted = _validate_sizes(size_sigmas, effects, owner)
    k_base, k_input, k_effects, k_sizes, k_noise = jax.random.split(key, 5)

    def effect_rng(root, effect: str) -> np.random.Generator:
        return _rng(jax.random.fold_in(root, DAMPER_EFFECT_NAMES.index(effect)), owner)

    if sizes_wanted is None:
        sizes_wanted = {
            e: float(effect_rng(k_sizes, e).uniform(*_DEFAULT_SIZES)) for e in effects
        }
    t, x, command, what_input = _excitation(_rng(k_input, owner), duration, rate)
    path = InputPath.from_samples(t, x, channels=command[None])
    floor = DamperFamily.YIELD_SHARE * float(np.max(np.abs(np.diff(x))))
    base, what_base = damper_base_truth(_rng(k_base, owner), floor)
    quiet = DamperTruth(base)

    def run(truth: DamperTruth, substeps: int | None = None) -> np.ndarray:
        solver = RK4(substeps=substeps or _truth_substeps(truth, path))
        return np.asarray(_run_jit(truth.astype(path.values.dtype), path, solver))

    def absorbable(reference: DamperTruth, y_ref: np.ndarray) -> np.ndarray:
        """The reference's output sensitivities to its base's parameters (forward
        differences, unit-RMS columns): the changes a refit of the base takes up
        to first order."""
        substeps = _truth_substeps(reference, path)
        columns = []
        for name in _ABSORBING:
            value = float(getattr(reference.base, name))
            step = 1e-6 * max(abs(value), 1.0)
            moved = eqx.tree_at(
                lambda m, name=name: getattr(m.base, name), reference, value + step
            )
            column = run(moved, substeps) - y_ref
            columns.append(column / max(_rms(column), 1e-300))
        return np.stack(columns, axis=1)

    y_base = run(quiet)
    noise_rng = _rng(k_noise, owner)
    peak = float(np.max(np.abs(y_base)))
    sigma = _loguniform(noise_rng, 0.005, 0.015) * peak
    velocity = np.diff(x) * rate
    components: dict[str, eqx.Module] = {}
    sizes, forms, lines = {}, {}, []
    for effect in effects:
        target = sizes_wanted[effect] * sigma
        reference = quiet
        if effect == "driver_lag":
            reference = eqx.tree_at(
                lambda m: m.field, quiet, components["field"], is_leaf=_none
            )
        y_reference = run(reference) if reference is not quiet else y_base
        columns = absorbable(reference, y_reference)

        def measure(
            field: str, component, reference=reference, y_ref=y_reference, cols=columns
        ):
            model = eqx.tree_at(
                lambda m: getattr(m, field), reference, component, is_leaf=_none
            )
            change = (run(model) - y_ref)[:, None]
            return _rms(project_off(cols, change, np.ones(change.shape[0])))

        sizer = _SIZERS[effect]
        field, component, reached, form, what = sizer(
            effect_rng(k_effects, effect), measure, target, base, velocity, duration
        )
        components[field] = component
        sizes[effect] = reached / sigma
        forms[effect] = form
        lines.append(f"{effect} [{form}]: {what}; size {sizes[effect]:.3g} sigma")
    truth = DamperTruth(base, **components)  # pyright: ignore[reportArgumentType]
    y_true = run(truth) if effects else y_base
    e, what_noise = _load_cell_noise(noise_rng, noise, sigma, y_true.shape[0])
    label = "+".join(effects) if effects else "clean"
    recording = Recording(
        t,
        x,
        y_true + e,
        name=f"damper-{label}-{noise}",
        input_name="displacement",
        output_name="force",
        input_unit="cm",
        output_unit="N",
        more_inputs={"command": command},
        more_input_units={"command": "V"},
    )
    tail = (
        f"noise: {what_noise}, sigma {sigma:.4g} N ({sigma / peak:.3%} of the peak "
        "force)"
    )
    body = lines or ["no effects (clean recording)"]
    return DamperCase(
        recording=recording,
        effects=effects,
        sigma=sigma,
        sizes=sizes,
        forms=forms,
        truth_description="\n".join([what_base, what_input, *body, tail]),
        truth=truth,
        base=base,
        noiseless=y_true,
        noise=noise,
        solver=RK4(substeps=_truth_substeps(truth, path)),
    )


def _none(x) -> bool:
    return x is None


# The base parameters a refit moves (A fixes z's scale; x0 only shifts like f0).
_ABSORBING = ("c0", "k0", "alpha", "f0", "beta", "gamma", "n")


# ----------------------------------------------------------------------- sizing


def _size_field(rng, measure, target, base, velocity, duration) -> _Sized:
    damping, internal = rng.uniform(0.05, 0.3), rng.uniform(0.0, 0.2)

    def sized(form: str, shape: float, words: str):
        def make(p):
            return FieldGrowth(form, p, damping * p, internal * p, shape)

        p, r = _solve_size(
            lambda p: measure("field", make(p)), target, 1.0, linear=False, most=20.0
        )
        what = (
            f"{words}: at {FULL_SCALE:g} V alpha x{1 + p:.4g}, c0 x{1 + damping * p:.4g}, "
            f"c1 x{1 + internal * p:.4g}"
        )
        return "field", make(p), r, form, what

    def exponential():
        q = rng.uniform(0.3, 1.0)
        return sized("exponential", q, f"saturating (1 - exp(-q/{q:.3g}))")

    def power():
        exponent = rng.uniform(0.5, 0.8)
        return sized("power", exponent, f"sub-linear q^{exponent:.3g}")

    return _first_reaching(target, _in_order(rng, [exponential, power]))


def _size_driver(rng, measure, target, base, velocity, duration) -> _Sized:
    def second_order():
        zeta = rng.uniform(0.6, 1.0)
        p, r = _solve_size(
            lambda p: measure("driver", SecondOrderDriver(p, zeta)),
            target,
            0.003,
            linear=False,
            most=0.03,
        )
        what = (
            f"second-order driver, 1/omega = {1e3 * p:.3g} ms ({1 / (2 * math.pi * p):.3g} "
            f"Hz), zeta {zeta:.3g}"
        )
        return "driver", SecondOrderDriver(p, zeta), r, "second_order", what

    def rate_limited():
        p, r = _solve_size(
            lambda p: measure("driver", RateLimitedDriver(p)),
            target,
            0.005,
            linear=False,
            most=0.05,
        )
        what = f"rate-limited driver: a full-scale step takes {1e3 * p:.3g} ms"
        return "driver", RateLimitedDriver(p), r, "rate_limited", what

    return _first_reaching(target, _in_order(rng, [second_order, rate_limited]))


def _size_rolloff(rng, measure, target, base, velocity, duration) -> _Sized:
    c0, k0 = float(base.c0), float(base.k0)
    spring = rng.uniform(0.5, 3.0) * k0

    def make(p):
        return InternalDashpot(c0 / p, spring)

    p, r = _solve_size(
        lambda p: measure("internal", make(p)), target, 0.05, linear=False, most=2.0
    )
    what = (
        f"Spencer's internal dashpot c1 = {c0 / p:.4g} N s/cm with an internal spring "
        f"{spring:.4g} N/cm"
    )
    return "internal", make(p), r, "spencer", what


def _size_offset(rng, measure, target, base, velocity, duration) -> _Sized:
    # A slow wander: a random walk smoothed over a quarter of the record (a zero
    # drifting over seconds to minutes, not within a cycle of the motion).
    num = 400
    walk = np.cumsum(rng.standard_normal(num))
    width = num // 4
    smooth = np.convolve(
        np.pad(walk, width, mode="edge"), np.ones(width) / width, mode="same"
    )[width:-width]
    smooth -= smooth[0]
    wander = smooth / max(_rms(smooth - smooth.mean()), 1e-30)
    share = rng.uniform(0.3, 0.7)
    # The dissipated power's scale: |F| ~ c0*|xdot| + the yield force.
    energy = (
        rng.uniform(0.2, 0.6)
        * duration
        * float(np.mean(np.abs(velocity) * (float(base.c0) * np.abs(velocity) + 150.0)))
    )

    def make(p):
        return Warming(p, energy, share * p, wander, duration)

    p, r = _solve_size(lambda p: measure("warming", make(p)), target, 10.0, linear=True)
    what = (
        f"preload rising by {p:.4g} N as the damper warms (e-folding at {energy:.4g} "
        f"N cm dissipated) and a load-cell wander of rms {share * p:.4g} N"
    )
    return "warming", make(p), r, "warming", what


def _size_asymmetry(rng, measure, target, base, velocity, duration) -> _Sized:
    sign = float(rng.choice([-1.0, 1.0]))

    def valving():
        v0 = rng.uniform(0.05, 0.3) * float(np.sqrt(np.mean(velocity**2)))
        p, r = _solve_size(
            lambda p: measure("valving", Valving(sign * p, v0)),
            target,
            0.1,
            linear=False,
            most=0.6,
        )
        what = (
            f"valving: c0*(1 + {sign * p:.3g}*tanh(xdot/{v0:.3g} cm/s)) "
            f"({'positive' if sign > 0 else 'negative'} velocity damped more)"
        )
        return "valving", Valving(sign * p, v0), r, "valving", what

    def side_yield():
        p, r = _solve_size(
            lambda p: measure("side", SideYield(sign * p)),
            target,
            0.1,
            linear=False,
            most=0.5,
        )
        what = f"side-dependent yield: z's level x(1 + {sign * p:.3g}*sign(z))"
        return "side", SideYield(sign * p), r, "yield", what

    return _first_reaching(target, _in_order(rng, [valving, side_yield]))


_SIZERS = {
    "field_dependence": _size_field,
    "driver_lag": _size_driver,
    "rolloff": _size_rolloff,
    "offset": _size_offset,
    "asymmetry": _size_asymmetry,
}
