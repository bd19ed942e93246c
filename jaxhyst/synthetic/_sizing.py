"""Sizing the piezo effects: each effect's truth form (a variant drawn from the
key) with its coefficient set by `_solve_size` to the requested RMS change."""

import math
from collections.abc import Callable
from typing import NamedTuple

import equinox as eqx
import numpy as np

from .._inputs import InputPath
from .._simulate import RK4, simulate
from ._random import _loguniform
from ._size_search import _rms, _solve_size
from ._truth import (
    _CREEP_MODES,
    _CREEP_TIMES,
    BranchBeta,
    ConcealedTruth,
    CubicStatic,
    KelvinElement,
    ModalResonance,
    PhaseFilter,
    PronyCreep,
    RateAmplitude,
    ThermalDrift,
)


_MAX_NATURAL_FREQUENCY = 150.0  # Hz, the fastest mode the truth may carry
_MIN_FILTER_LAG = 2e-3  # s, the fastest pole of the input-bias filter


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
