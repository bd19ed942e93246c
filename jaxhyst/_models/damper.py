"""Magnetorheological (MR) damper models: force from an imposed displacement x and,
for the controllable damper, a command voltage v (two inputs: `input_names`).

`BoucWenDamper` is the family's base, a damper of fixed field (Bouc-Wen hysteresis
beside a dashpot and a spring); `SpencerDamper` is Spencer, Dyke, Sain and Carlson's
"modified Bouc-Wen" model (J. Eng. Mech. 123(3), 1997), whose parameters depend on
the command through a first-order filter.
"""

import math
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, Int

from .._inputs import InputPath
from .._recording import Recording
from .._simulate import RK4
from .._smoothing import AbstractSmoothing, ExactSign
from .base import (
    AbstractDrive,
    AbstractHysteresisModel,
    BoucWenShape,
    DataScales,
    Drive,
    SearchBox,
    as_parameter,
    hysteretic_rate,
    read_input,
    smoothing_field,
)


class AbstractDamperDrive(AbstractDrive):
    """What an MR damper model reads at one time: the displacement x (`u`), its
    velocity xdot (`udot`), the command voltage v and its rate."""

    v: eqx.AbstractVar[Float[Array, ""]]
    vdot: eqx.AbstractVar[Float[Array, ""]]

    @property
    def x(self) -> Float[Array, ""]:
        return self.u

    @property
    def xdot(self) -> Float[Array, ""]:
        return self.udot


class DamperDrive(AbstractDamperDrive):
    """What an MR damper model reads at one time: the displacement x (`u`), its
    velocity xdot (`udot`), the command voltage v and its rate."""

    u: Float[Array, ""]
    udot: Float[Array, ""]
    v: Float[Array, ""]
    vdot: Float[Array, ""]


def read_command(
    path: InputPath,
    t: Float[ArrayLike, ""],
    interval: Int[ArrayLike, ""] | None,
    frac: Float[ArrayLike, ""] | None,
) -> tuple[Float[Array, ""], Float[Array, ""]]:
    """(v, vdot), the first further input (`path.channels` row 0) at `t`, on the
    given sample interval when one is known (as `read_input` reads the first)."""
    if interval is None or frac is None:
        values, rates = path.channels_at(t)
    else:
        values, rates = path.channels_on_interval(interval, frac)
    return values[0], rates[0]


def _damping_range(scales: DataScales) -> tuple[float, float]:
    """Bounds of a viscous coefficient (force per velocity): the record does not say
    which velocities it reached, so they span every time scale it can show, from a
    Nyquist period (1/(pi*fs)) to the whole record (duration/(2*pi)), around
    max|F|/max|x|."""
    stiffness = scales.output_peak / scales.input_peak
    fastest = 1.0 / (math.pi * scales.sample_rate)
    slowest = scales.duration / (2 * math.pi)
    return 1e-2 * stiffness * fastest, 10.0 * stiffness * slowest


def _shape_bounds(scales: DataScales) -> dict[str, tuple[float, float]]:
    """beta, gamma and n with A = 1 (z in displacement units): beta + gamma ~
    1/z_y^n for a yield displacement z_y from ~2e-5*max|x| to several max|x| at
    n = 2 (MR fluids yield within a small fraction of the stroke). Searched
    positive: the published MR sets have beta = gamma > 0 (a loop that saturates,
    Table 2's stable class)."""
    su = scales.input_peak
    return {
        "beta": (1e-2 / su**2, 1e9 / su**2),
        "gamma": (1e-2 / su**2, 1e9 / su**2),
        "n": (1.0, 3.0),
    }


def _saturation(A: float, beta: float, gamma: float, n: float) -> float:
    """z_u = (A/(beta + gamma))^(1/n), where the Bouc-Wen variable saturates."""
    return (abs(A) / max(beta + gamma, 1e-30)) ** (1.0 / n)


def _hysteretic_rate_bound(
    A: float, beta: float, gamma: float, n: float, relative: float
) -> float:
    """|d zdot/dz| <= n*(|beta| + |gamma|)*z_u^(n-1)*|rate| of the Bouc-Wen law,
    with |z| <= z_u and |rate| <= `relative`: large for a sharp loop (small z_u)
    at high velocity, which is what makes MR damper models stiff."""
    z_u = _saturation(A, beta, gamma, n)
    return n * (abs(beta) + abs(gamma)) * z_u ** (n - 1) * relative


def _peak_rate(inputs: InputPath) -> float:
    """The largest |xdot| of the piecewise-linear displacement the models see."""
    x = np.asarray(inputs.values)
    return float(np.max(np.abs(np.diff(x)))) / float(inputs.dt)


def _substeps(rate: float, dt: float, per_step: float) -> int:
    return max(1, math.ceil(rate * dt / per_step))


def _recommended_solver(
    model: "BoucWenDamper | SpencerDamper", recording: Recording
) -> RK4:
    return RK4(substeps=model.recommended_substeps(recording.input_path()))


class BoucWenDamper(AbstractHysteresisModel[Drive]):
    """A damper of fixed field: a dashpot, a spring and Bouc-Wen hysteresis in
    parallel (the "Bouc-Wen model" Spencer et al. 1997 start from, plus an offset):

        F    = c0*xdot + k0*(x - x0) + alpha*z + f0
        zdot = A*xdot - beta*|xdot|*|z|^(n-1)*z - gamma*xdot*|z|^n

    x is the displacement, F the force. It reads no command (`input_names` is the
    displacement alone): fit it to a record at one constant voltage. x0 and f0 enter
    only as the offset f0 - k0*x0 (x0 is kept for the paper's form; the default box
    fixes it at 0), and (A, alpha, beta, gamma) carry the symmetry z -> c*z. State: z.

    A sharp loop is stiff: zdot relaxes at up to n*(beta + gamma)*z_u^(n-1)*|xdot|
    (z_u the saturation), so pick the RK4 substeps with `recommended_substeps`.
    """

    c0: Float[Array, ""] = eqx.field(converter=as_parameter)
    k0: Float[Array, ""] = eqx.field(converter=as_parameter)
    x0: Float[Array, ""] = eqx.field(converter=as_parameter)
    alpha: Float[Array, ""] = eqx.field(converter=as_parameter)
    f0: Float[Array, ""] = eqx.field(converter=as_parameter)
    A: Float[Array, ""] = eqx.field(converter=as_parameter)
    beta: Float[Array, ""] = eqx.field(converter=as_parameter)
    gamma: Float[Array, ""] = eqx.field(converter=as_parameter)
    n: Float[Array, ""] = eqx.field(converter=as_parameter)
    smoothing: AbstractSmoothing = smoothing_field()

    state_size: ClassVar[int] = 1
    input_names: ClassVar[tuple[str, ...]] = ("displacement",)

    def vector_field(self, t, state, drive):
        zdot = hysteretic_rate(
            self.smoothing,
            state[0],
            drive.udot,
            self.A,
            self.beta,
            self.gamma,
            self.n,
        )
        return jnp.stack([zdot])

    def output(self, t, state, drive):
        return (
            self.c0 * drive.udot
            + self.k0 * (drive.u - self.x0)
            + self.alpha * state[0]
            + self.f0
        )

    def stiffness(self, velocity: float) -> float:
        """An estimate (1/s) of the fastest rate of zdot at velocities up to
        `velocity`: n*(|beta| + |gamma|)*z_u^(n-1)*|xdot| at the saturation
        z_u = (A/(beta + gamma))^(1/n). Needs concrete parameter values."""
        p = {name: float(value) for name, value in self.parameters().items()}
        return _hysteretic_rate_bound(
            p["A"], p["beta"], p["gamma"], p["n"], abs(velocity)
        )

    def recommended_substeps(self, inputs: InputPath, *, per_step: float = 1.75) -> int:
        """RK4 substeps per sample interval for `inputs`, as
        `SpencerDamper.recommended_substeps`: `stiffness` at the record's peak
        velocity times the step at most `per_step`. A sharp loop (small z_u) at
        high velocity needs several."""
        return _substeps(self.stiffness(_peak_rate(inputs)), float(inputs.dt), per_step)

    def default_solver(self, recording: Recording) -> RK4:
        """RK4 with `recommended_substeps` for the record: a sharp loop at high
        velocity is stiff at kHz sample rates."""
        return _recommended_solver(self, recording)

    def default_bounds(self, scales: DataScales, *, gauge: bool = True) -> SearchBox:
        """Bounds scaled to max|x| and max|F|. x0 is fixed at 0 (f0 carries the
        offset). With `gauge=True` (default) A is fixed at 1, which gives z the units
        of displacement and removes the z -> c*z symmetry (any fit with A > 0 maps
        onto it); `gauge=False` searches A in [1e-3, 1e3] too. With K = max|F|/max|x|:
        c0 from 1e-2*K/(pi*fs) to 10*K*duration/(2*pi) (every time scale the
        record can show, as its velocities are unknown), k0 1e-4..10 K, alpha
        1e-2..1e4 K (alpha*z_y is the yield force, and z_y may be small), f0 within
        +-max|F|, beta and gamma 1e-2..1e9 / max|x|^2 (a yield displacement down to
        ~2e-5*max|x| at n = 2; positive: a loop that saturates), n in [1, 3]; c0, k0,
        alpha, A, beta and gamma on a log scale."""
        su, sy = scales.input_peak, scales.output_peak
        bounds = {
            "c0": _damping_range(scales),
            "k0": (1e-4 * sy / su, 10 * sy / su),
            "alpha": (1e-2 * sy / su, 1e4 * sy / su),
            "f0": (-sy, sy),
            "A": (1e-3, 1e3),
            **_shape_bounds(scales),
        }
        log = ("c0", "k0", "alpha", "A", "beta", "gamma")
        template = self.replace(x0=0.0)
        if gauge:
            del bounds["A"]
            log = tuple(name for name in log if name != "A")
            template = template.replace(A=1.0)
        return SearchBox(template, bounds, log)

    def bouc_wen_shape(self) -> BoucWenShape:
        return BoucWenShape(
            self.A, self.beta, self.gamma, self.n, names=("A", "beta", "gamma", "n")
        )


class SpencerDamper(AbstractHysteresisModel[DamperDrive]):
    """Spencer, Dyke, Sain and Carlson's "modified Bouc-Wen" MR damper model
    (J. Eng. Mech. 123(3):230-238, 1997): the Bouc-Wen element and a
    dashpot c0 with spring k0 act on an internal displacement y, tied to the piston
    through a second dashpot c1; an accumulator spring k1 sits in parallel.

        F    = c1*ydot + k1*(x - x0)
        ydot = (alpha*z + c0*xdot + k0*(x - y)) / (c0 + c1)
        zdot = A*(xdot - ydot) - beta*|xdot - ydot|*|z|^(n-1)*z
               - gamma*(xdot - ydot)*|z|^n
        alpha = alpha_a + alpha_b*w,  c1 = c1a + c1b*w,  c0 = c0a + c0b*w
        wdot = -eta*(w - v)

    Inputs: the displacement x and the command voltage v (`input_names`); w is the
    command filtered by the fluid's rheology and the coil's inductance. (The paper
    writes gamma on the |xdot - ydot| term and beta on the other, the reverse of
    this package's Bouc-Wen law; its published values have beta = gamma, so they
    read the same.) State: (z, y, w), starting at z = 0, y = x(0), w = v(0): a
    demagnetised damper at rest with its command settled.

    The model is stiff: through the internal dashpot z relaxes at about
    A*alpha/(c0 + c1) (1.6e3 1/s at 2.25 V with the published values), and the
    hysteretic term adds up to n*(beta + gamma)*|z|^(n-1)*|xdot - ydot| (2e4 1/s at
    24 cm/s). With the published values, the largest eigenvalue of the state
    equations times the sample interval (3004.8 Hz) reaches 6.7 on a 1.5 cm, 2.5 Hz
    sine and 17 on the Dyke white-noise record (59 cm/s), past RK4's stability limit
    (2.8): one RK4 step per sample diverges. Pick the substeps with
    `recommended_substeps(inputs)` (5 and 11 there; 4 and 5 are the fewest within
    1e-3 of the peak force).
    """

    c0a: Float[Array, ""] = eqx.field(converter=as_parameter)
    c0b: Float[Array, ""] = eqx.field(converter=as_parameter)
    k0: Float[Array, ""] = eqx.field(converter=as_parameter)
    c1a: Float[Array, ""] = eqx.field(converter=as_parameter)
    c1b: Float[Array, ""] = eqx.field(converter=as_parameter)
    k1: Float[Array, ""] = eqx.field(converter=as_parameter)
    x0: Float[Array, ""] = eqx.field(converter=as_parameter)
    alpha_a: Float[Array, ""] = eqx.field(converter=as_parameter)
    alpha_b: Float[Array, ""] = eqx.field(converter=as_parameter)
    A: Float[Array, ""] = eqx.field(converter=as_parameter)
    beta: Float[Array, ""] = eqx.field(converter=as_parameter)
    gamma: Float[Array, ""] = eqx.field(converter=as_parameter)
    n: Float[Array, ""] = eqx.field(converter=as_parameter)
    eta: Float[Array, ""] = eqx.field(converter=as_parameter)
    smoothing: AbstractSmoothing = smoothing_field()

    state_size: ClassVar[int] = 3
    input_names: ClassVar[tuple[str, ...]] = ("displacement", "command")

    @classmethod
    def spencer_1997(
        cls, *, smoothing: AbstractSmoothing | None = None
    ) -> "SpencerDamper":
        """The parameters Spencer et al. (1997) identified for their
        prototype damper, in N, cm, s and V (the units of the Dyke white-noise
        records): c0a 21.0 N s/cm, c0b 3.50 N s/(cm V), k0 46.9 N/cm, c1a 283 N s/cm,
        c1b 2.95 N s/(cm V), k1 5.00 N/cm, x0 14.3 cm, alpha_a 140 N/cm, alpha_b
        695 N/(cm V), beta = gamma = 363 cm^-2, A 301, n 2, eta 190 1/s."""
        return cls(
            c0a=21.0,
            c0b=3.50,
            k0=46.9,
            c1a=283.0,
            c1b=2.95,
            k1=5.00,
            x0=14.3,
            alpha_a=140.0,
            alpha_b=695.0,
            A=301.0,
            beta=363.0,
            gamma=363.0,
            n=2.0,
            eta=190.0,
            smoothing=ExactSign() if smoothing is None else smoothing,
        )

    def drive(self, path: InputPath, t, interval=None, frac=None) -> DamperDrive:
        x, xdot = read_input(path, t, interval, frac)
        v, vdot = read_command(path, t, interval, frac)
        return DamperDrive(x, xdot, v, vdot)

    def _coefficients(self, w):
        """(alpha, c0, c1) at filtered command w."""
        return (
            self.alpha_a + self.alpha_b * w,
            self.c0a + self.c0b * w,
            self.c1a + self.c1b * w,
        )

    def _internal_rate(self, state, drive: AbstractDrive):
        """(ydot, c1): the internal displacement's rate and the c1 it sees."""
        z, y, w = state[0], state[1], state[2]
        alpha, c0, c1 = self._coefficients(w)
        ydot = (alpha * z + c0 * drive.udot + self.k0 * (drive.u - y)) / (c0 + c1)
        return ydot, c1

    def vector_field(self, t, state, drive: DamperDrive):
        ydot, _ = self._internal_rate(state, drive)
        zdot = hysteretic_rate(
            self.smoothing,
            state[0],
            drive.udot - ydot,
            self.A,
            self.beta,
            self.gamma,
            self.n,
        )
        wdot = -self.eta * (state[2] - drive.v)
        return jnp.stack([zdot, ydot, wdot])

    def output(self, t, state, drive):
        ydot, c1 = self._internal_rate(state, drive)
        return c1 * ydot + self.k1 * (drive.u - self.x0)

    def initial_state(self, drive: DamperDrive):
        x = jnp.asarray(drive.u)
        return jnp.stack([jnp.zeros_like(x), x, jnp.asarray(drive.v, x.dtype)])

    def stiffness(self, velocity: float, commands: tuple[float, ...] = (0.0,)) -> float:
        """An estimate (1/s) of the fastest rate of the state equations (the
        largest |eigenvalue| of their Jacobian) at velocities up to `velocity`, the
        largest over the filtered `commands` given (the ends of the command's
        range). The hysteretic term's n*(|beta| + |gamma|)*z_u^(n-1)*|xdot - ydot|
        dominates, at the saturation z_u = (A/(beta + gamma))^(1/n) and
        |xdot - ydot| <= (c1*|xdot| + alpha*z_u)/(c0 + c1); z relaxes through the
        internal dashpot at A*alpha/(c0 + c1), the filter at eta. With the
        published values it is within 10 % of the measured largest eigenvalue on a
        2.5 Hz sine at 0 V and on the Dyke white-noise record, 1.5 times it at
        2.25 V. Needs concrete parameter values (not under jit)."""
        p = {name: float(value) for name, value in self.parameters().items()}
        A, beta, gamma, n = p["A"], p["beta"], p["gamma"], p["n"]
        z_u = _saturation(A, beta, gamma, n)
        fastest = 0.0
        for w in commands:
            alpha = abs(p["alpha_a"] + p["alpha_b"] * w)
            c1 = abs(p["c1a"] + p["c1b"] * w)
            total = max(p["c0a"] + p["c0b"] * w + c1, 1e-30)
            relative = (c1 * abs(velocity) + alpha * z_u) / total
            rate = abs(A) * alpha / total + _hysteretic_rate_bound(
                A, beta, gamma, n, relative
            )
            fastest = max(fastest, rate)
        return fastest + abs(p["eta"])

    def recommended_substeps(self, inputs: InputPath, *, per_step: float = 1.75) -> int:
        """RK4 substeps per sample interval for simulating `inputs`: enough that
        `stiffness` (at the record's peak velocity, over its command range) times the
        step is at most `per_step`. The default keeps the scan-RK4 within 1e-3 of the
        peak force of a tight diffrax solve with the published values (2.5 Hz sines at
        0 and 2.25 V, the Dyke white-noise record; tests/test_damper.py): 5 substeps
        for a 1.5 cm, 2.5 Hz sine at 3004.8 Hz. RK4 is stable up to 2.8, and its error
        grows fast beyond ~2. Needs concrete parameter values (not under jit)."""
        if inputs.channels is None:
            commands = (0.0,)
        else:
            v = np.asarray(inputs.channels[0])
            commands = (float(np.min(v)), float(np.max(v)))
        rate = self.stiffness(_peak_rate(inputs), commands)
        return _substeps(rate, float(inputs.dt), per_step)

    def default_solver(self, recording: Recording) -> RK4:
        """RK4 with `recommended_substeps` for the record: the internal dashpot and a
        sharp loop are stiff at kHz sample rates."""
        return _recommended_solver(self, recording)

    def default_bounds(self, scales: DataScales, *, gauge: bool = True) -> SearchBox:
        """Bounds scaled to max|x|, max|F| and the peak command (`more_input_peaks[0]`,
        1 V if the scales have none). With `gauge=True` (default) A is fixed at 1,
        which gives z the units of displacement and removes the z -> c*z symmetry of
        (A, alpha_a, alpha_b, beta, gamma); `gauge=False` searches A in [1e-3, 1e3].
        The dashpots, springs, alpha_a, beta, gamma and n span `BoucWenDamper`'s
        ranges for c0, k0, alpha, beta, gamma and n; x0 is within +-30*max|x|
        (k1*x0 is the accumulator's preload), eta from 1/duration to the sample rate
        (a faster filter is a step at this sampling). The command terms (c0b, c1b,
        alpha_b) span the same ranges per peak command; a field only strengthens the
        fluid, so every coefficient but x0 and n is searched positive on a log
        scale."""
        su, sy = scales.input_peak, scales.output_peak
        peaks = scales.more_input_peaks
        sv = peaks[0] if peaks and peaks[0] > 0 else 1.0
        damping = _damping_range(scales)
        stiffness = (1e-4 * sy / su, 10 * sy / su)
        yielding = (1e-2 * sy / su, 1e4 * sy / su)
        bounds = {
            "c0a": damping,
            "c0b": (damping[0] / sv, damping[1] / sv),
            "k0": stiffness,
            "c1a": damping,
            "c1b": (damping[0] / sv, damping[1] / sv),
            "k1": stiffness,
            "x0": (-30 * su, 30 * su),
            "alpha_a": yielding,
            "alpha_b": (yielding[0] / sv, yielding[1] / sv),
            "A": (1e-3, 1e3),
            **_shape_bounds(scales),
            "eta": (1.0 / scales.duration, scales.sample_rate),
        }
        log = tuple(name for name in bounds if name not in ("x0", "n"))
        template = self
        if gauge:
            del bounds["A"]
            log = tuple(name for name in log if name != "A")
            template = self.replace(A=1.0)
        return SearchBox(template, bounds, log)

    def bouc_wen_shape(self) -> BoucWenShape:
        return BoucWenShape(
            self.A, self.beta, self.gamma, self.n, names=("A", "beta", "gamma", "n")
        )
