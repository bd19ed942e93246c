"""Sizing the structural effects: two truth forms per mechanical effect, the first
(drawn from the key) that reaches the requested RMS change.

Each effect's size is *set*: its coefficient is rescaled (exactly where the force is
linear in it, by the safeguarded secant search `_solve_size` where it is not) until
the RMS of (F with the effect - F without it) equals the requested number of noise
sigmas.
"""

import math
from collections.abc import Callable
from typing import NamedTuple

import equinox as eqx
import numpy as np

from .._inputs import InputPath
from .._simulate import RK4, simulate
from ._size_search import _first_reaching, _in_order, _rms, _Sized, _solve_size
from ._structural_truth import (
    DuctilityDegradation,
    DuctilityPinching,
    EnergyDegradation,
    LoadCellDrift,
    OneSidedHardening,
    SideYield,
    SlipGap,
    StructuralTruth,
)


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
