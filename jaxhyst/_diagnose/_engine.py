"""The diagnosis loop: fit the base model, score every catalogue effect on the
residual, refit the strongest candidates, keep an effect only if it earns its
parameters on held-out data, and repeat until nothing significant is left."""

import dataclasses
import math
import time
from typing import Any, cast

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import PRNGKeyArray

from .._identify import (
    Fit,
    LevenbergMarquardtPolish,
    Problem,
    _decimate,
    _model_at,
    _problem_rmse,
    _swarm_objective,
    identify,
)
from .._metrics import error_metrics
from .._models.base import AbstractHysteresisModel
from .._models.bouc_wen import PiezoBoucWen
from .._models.extended import ExtendedPiezo
from .._params import ParameterSpace
from .._placement import moved_to, running_on, serial_device
from .._recording import Recording
from .._simulate import RK4, simulate
from .._swarm import MPSO, run_swarm
from ._catalogue import CATALOGUE, EFFECT_NAMES
from ._locate import describe, effective_samples, locate


BASE_FREE = ("k1", "k2", "beta1", "gamma1", "n")  # A1 fixes the gauge
MAX_REFITS_PER_ROUND = 3


class Finding(eqx.Module):
    """One adopted effect, with the evidence for it and what it bought."""

    effect: str
    evidence: str
    where: str
    score: float
    parameters: dict[str, float]
    before: dict[str, float]
    after: dict[str, float]
    validation: dict[str, Any]

    def to_dict(self) -> dict[str, Any]:
        return {
            "effect": self.effect,
            "evidence": self.evidence,
            "where": self.where,
            "score": self.score,
            "parameters": self.parameters,
            "before": self.before,
            "after": self.after,
            "validation": self.validation,
        }


class Diagnosis(eqx.Module):
    """The result of `diagnose`; `to_dict()` is the `jaxhyst diagnose` JSON."""

    recording: str
    samples: int
    base_model: AbstractHysteresisModel
    final_model: AbstractHysteresisModel
    baseline: dict[str, float]
    final: dict[str, float]
    findings: list[Finding]
    candidates: list[list[dict[str, Any]]]
    ambiguities: list[str]
    noise_sigma: float
    noise: dict[str, float]
    location: dict[str, Any]
    base_predicted: np.ndarray
    final_predicted: np.ndarray
    holdout_fraction: float
    seconds: float

    @property
    def effects(self) -> tuple[str, ...]:
        return tuple(f.effect for f in self.findings)

    @property
    def final_rmse(self) -> float:
        return self.final["rmse"]

    def to_dict(self) -> dict[str, Any]:
        adopted = "+".join(self.effects)
        return {
            "recording": self.recording,
            "samples": self.samples,
            "model": "piezo",
            "noise": self.noise,
            "baseline": self.baseline,
            "findings": [f.to_dict() for f in self.findings],
            "final": {
                "model": "piezo" + (f"+{adopted}" if adopted else ""),
                "rmse": self.final["rmse"],
                "metrics": self.final,
                "parameters": _active_parameters(self.final_model, self.effects),
            },
            "ambiguities": self.ambiguities,
            "location": self.location,
            "candidates": self.candidates,
            "holdout_fraction": self.holdout_fraction,
            "timing": {"total_s": self.seconds},
        }


def _active_parameters(model, effects) -> dict[str, float]:
    names = list(PiezoBoucWen.parameter_names)
    for effect in effects:
        names += list(CATALOGUE[effect].parameters)
    return {n: float(getattr(model, n)) for n in names}


# ----------------------------------------------------------------- linear algebra


@eqx.filter_jit
def _output_jacobian(model, names, inputs, solver):
    values = jnp.stack([jnp.asarray(getattr(model, n), float) for n in names])

    def outputs(v):
        new = eqx.tree_at(
            lambda m: [getattr(m, n) for n in names],
            model,
            [v[i] for i in range(len(names))],
        )
        return simulate(new, inputs, solver, throw=False)

    return jax.jacfwd(outputs)(values)


def _jacobian(model, names, inputs, solver) -> np.ndarray:
    """d output / d parameter for `names` (one compilation per model structure)."""
    return np.nan_to_num(
        np.asarray(_output_jacobian(model, tuple(names), inputs, solver))
    )


def _dynamics_directions(predicted: np.ndarray, dt: float) -> np.ndarray:
    """First-order effect of a fast stage on the output: y ~ y_s - a1*y_s' - a2*y_s''
    with a1 = 2*zeta/omega and a2 = 1/omega^2."""
    first = np.gradient(predicted, dt)
    second = np.gradient(first, dt)
    return -np.stack([first, second], axis=1)


def _project_off(base: np.ndarray, extra: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The part of `extra`'s columns that the base parameters cannot absorb."""
    bw = base * w[:, None]
    ew = extra * w[:, None]
    coef, *_ = np.linalg.lstsq(bw, ew, rcond=None)
    return ew - bw @ coef


def _whitening_filter(noise: np.ndarray, order: int = 2) -> np.ndarray:
    """AR(order) coefficients of `noise` (least squares), used to pre-whiten the
    score test so that coloured sensor noise does not pass for physics."""
    x = noise - noise.mean()
    lagged = np.stack([x[order - k - 1 : x.size - k - 1] for k in range(order)], axis=1)
    coef, *_ = np.linalg.lstsq(lagged, x[order:], rcond=None)
    return coef


def _whiten(x: np.ndarray, coef: np.ndarray) -> np.ndarray:
    out = np.array(x, dtype=float, copy=True)
    for k, a in enumerate(coef, start=1):
        out[k:] -= a * x[:-k]
    return out


def _score(directions: np.ndarray, residual: np.ndarray, coef: np.ndarray, sigma2):
    """Lagrange-multiplier statistic of the pre-whitened residual along the
    pre-whitened directions: s^T (D^T D)^-1 s / sigma^2, ~ chi^2(dof) under no effect."""
    d = _whiten(directions, coef)
    r = _whiten(residual, coef)
    s = d.T @ r
    try:
        stat = float(s @ np.linalg.solve(d.T @ d, s)) / sigma2
    except np.linalg.LinAlgError:
        stat = 0.0
    return max(stat, 0.0)


def _max_canonical_correlation(a: np.ndarray, b: np.ndarray) -> float:
    qa, _ = np.linalg.qr(a)
    qb, _ = np.linalg.qr(b)
    return float(np.linalg.svd(qa.T @ qb, compute_uv=False).max(initial=0.0))


def _moving_columns(cols: np.ndarray) -> np.ndarray:
    """`cols` without the columns that are zero (parameters that move nothing)."""
    norms = np.linalg.norm(cols, axis=0)
    return cols[:, norms > 1e-9 * max(float(norms.max(initial=0.0)), 1e-300)]


def _effect_columns(effect: str, column: dict[str, np.ndarray]) -> np.ndarray:
    """The output's sensitivities to an effect's parameters (those that move it)."""
    rows = len(next(iter(column.values())))
    cols = [column[p] for p in CATALOGUE[effect].parameters if p in column]
    if not cols:
        return np.zeros((rows, 0))
    return _moving_columns(np.stack(cols, axis=1))


def _standing_in(
    results, signatures: dict[str, np.ndarray], adopted: dict[str, np.ndarray]
) -> list[str]:
    """Ambiguities for rejected candidates that beat the held-out noise and the
    information criterion, and failed only the 5 % floor, while their signature
    (`signatures[effect]`: output sensitivities, columns) overlaps an adopted
    effect's (`adopted[effect]`): the adopted effect may be standing in for them
    (e.g. a slow creep mode and a thermal drift on a record whose input mean is
    steady)."""
    messages = []
    for result in results:
        v = result["validation"]
        gain = v["heldout_rmse_before"] ** 2 - v["heldout_rmse_after"] ** 2
        if v["accepted"] or gain <= v["heldout_resolution_mse"] or v["bic_change"] >= 0:
            continue
        effect = result["candidate"]["effect"]
        raw = _moving_columns(signatures[effect])
        for name, cols in adopted.items():
            if raw.shape[1] == 0 or cols.shape[1] == 0:
                continue
            overlap = _max_canonical_correlation(raw, cols)
            if overlap > 0.9:
                percent = 100 * gain / v["heldout_rmse_before"] ** 2
                messages.append(
                    f"{effect} may also be present: adding it lowered the held-out "
                    f"error by {percent:.1f} % (more than its noise, and the "
                    "information criterion agrees), short of the 5 % adoption needs; "
                    f"its signature overlaps that of {name} (canonical correlation "
                    f"{overlap:.2f}), which may be standing in for part of it. Hold "
                    "the input at different levels and vary the rates to separate "
                    "them."
                )
                break
    return messages


# ------------------------------------------------------------------------- refits


def _bounds_around(model, names, natural_scales, fs, duration):
    bounds = {}
    for name in names:
        value = float(getattr(model, name))
        if name == "n":
            bounds[name] = (1.0, 4.0)
        elif name == "natural_frequency":
            bounds[name] = (2.0 / duration, 0.5 * fs)
        elif name == "damping_ratio":
            bounds[name] = (5e-3, 5.0)
        elif name in ("viscous_time", "input_time"):
            bounds[name] = (4.0 / fs, 2.0)
        elif name == "input_lead":
            bounds[name] = (-2.5, 3.0)
        elif name == "phi":
            reach = min(0.05 * duration, 0.5)
            bounds[name] = (value - reach, value + reach)
        elif name in natural_scales:
            scale = natural_scales[name]
            bounds[name] = (value - scale, value + scale)
        else:
            spread = 2 * abs(value) + 1e-12
            bounds[name] = (value - spread, value + spread)
    log = [
        n
        for n in ("natural_frequency", "damping_ratio", "viscous_time", "input_time")
        if n in names
    ]
    return bounds, log


# One RK4 step per sample: the quasi-static part is slow on the sample scale and the
# stage (when `dynamic`) is propagated exactly per sample by the model.
SOLVER = RK4()

ALL_NAMES = tuple(n for n in ExtendedPiezo.parameter_names if n != "A1")
STATIC_NAMES = tuple(
    n for n in ALL_NAMES if n not in ("natural_frequency", "damping_ratio")
)


@eqx.filter_jit
def _predict_jit(model, inputs):
    return simulate(model, inputs, SOLVER, throw=False)


def _predict(model: AbstractHysteresisModel, inputs) -> np.ndarray:
    """The model's output at every sample (NaN/inf where it diverges)."""
    return np.asarray(_predict_jit(model, inputs))


def _resolution(noise_sd: float, change: float, n_eff: float) -> float:
    """How small a held-out MSE difference can be told from noise, for two fits
    whose outputs differ by `change` (rms): ~3 x its standard error 2*sigma*change/
    sqrt(N_eff)."""
    return 3 * 2 * noise_sd * change / math.sqrt(n_eff)


def _starting_points(effect, current, step, fs):
    """Candidate starting models for an effect: the score test's Gauss-Newton step
    at several lengths, plus a grid over the effect's physical scale where the
    linearisation is known to be poor (time shifts, resonances)."""
    if effect == "dynamics":
        a1 = step.get("natural_frequency", 0.0)
        a2 = step.get("damping_ratio", 0.0)
        points = []
        if a2 > 0 and a1 > 0:
            omega = 1 / math.sqrt(a2)
            zeta = min(2.0, max(0.01, a1 * omega / 2))
            points.append((min(0.45 * fs, omega / (2 * math.pi)), zeta))
        points += [(fs / d, z) for d in (40, 20, 10, 5, 2.5) for z in (0.05, 0.2, 0.5)]
        return [current.with_dynamics(f, z) for f, z in points]
    models = [
        current.replace(
            **{p: float(getattr(current, p)) + scale * v for p, v in step.items()}
        )
        for scale in (0.25, 0.5, 1.0, 2.0, 4.0)
    ]
    if effect == "rate_dependence" and step.get("viscous"):
        # A viscoelastic element saturates above 1/time: longer times need more gain.
        viscous = float(current.viscous) + step["viscous"]
        models += [
            current.replace(viscous=gain * viscous, viscous_time=time)
            for time in (0.005, 0.01, 0.02, 0.05, 0.1)
            for gain in (1.0, 2.0, 4.0)
        ]
    if effect == "input_bias":
        shifts = [s * 1e-3 for s in (0.5, 1, 2, 5, 10, 20, 50, 100)]
        models += [current.replace(phi=sign * s) for s in shifts for sign in (1, -1)]
        # A network between drive and actuator: an RC lag or a lead, 5-50 ms.
        models += [
            current.replace(input_lead=lead, input_time=time)
            for lead in (-0.9, -0.5, 0.5, 1.0)
            for time in (0.005, 0.02, 0.05)
        ]
    return models


def _best_start(effect, current, step, inputs, y, mask, fs):
    """The starting point with the lowest error on the fitted samples."""
    best, best_mse = current, float("inf")
    for trial in _starting_points(effect, current, step, fs):
        pred = _predict(trial, inputs)
        if not np.all(np.isfinite(pred)):
            continue
        mse = float(np.mean((y - pred)[mask] ** 2))
        if mse < best_mse:
            best, best_mse = trial, mse
    return best, best_mse


def _refit(
    model,
    names,
    inputs,
    measured,
    weights,
    natural_scales,
    fs,
    duration,
    max_steps=40,
    key=None,
):
    """Levenberg-Marquardt over `names` (the rest frozen) in one fixed space, on a
    decimated copy when the model is quasi-static (its loss depends on turning
    points, not on the sample rate). With a `key`, a short swarm over the same space
    first looks for a better basin: a large effect can pull the base parameters far
    from where the base fit left them."""
    bounds, log = _bounds_around(model, ALL_NAMES, natural_scales, fs, duration)
    frozen = [n for n in ALL_NAMES if n not in names]
    space = ParameterSpace(model, bounds, log_scale=log, frozen=frozen)
    solver = SOLVER
    problem = Problem(space, inputs, measured, solver, weights)
    # Quasi-static fits see turning points, not the sample rate: 250 Hz is plenty.
    # A resonance needs >= 4 samples per period at its starting frequency.
    slowest = 4 * float(model.natural_frequency) if model.dynamic else 250.0
    stride = max(1, int(fs // max(250.0, slowest)))
    if stride > 1 and inputs.num_samples > 20 * stride:
        problem = _decimate(problem, stride)
    z0 = space.from_model(model)
    if key is not None and not model.dynamic:
        coarse_stride = max(1, inputs.num_samples // 2000)
        coarse = _decimate(problem, max(1, coarse_stride // stride))
        swarm = run_swarm(
            _swarm_objective,
            jnp.zeros(space.dimension),
            jnp.ones(space.dimension),
            MPSO(num_particles=48, num_iterations=100),
            key,
            args=coarse,
            chunk_size=20,
            stall_iterations=20,
        )
        if float(_problem_rmse(problem, swarm.best_x)) < float(
            _problem_rmse(problem, z0)
        ):
            z0 = swarm.best_x
    # Decimated quasi-static fits (screening, converging, final) come in many free
    # sets and are cheap per step: one padded size for all of them. Full-rate ones
    # (a stage resonance) are expensive per tangent: the tightest size.
    active = _ActiveProblem.build(
        problem,
        z0,
        [ALL_NAMES.index(n) for n in names],
        smallest=11 if problem.measured.size < inputs.num_samples else 8,
    )
    polish = LevenbergMarquardtPolish(max_steps=max_steps, min_gain=1e-5)
    # `_ActiveProblem` offers the part of `Problem` a polish uses.
    result = polish.run(active, active.start())  # pyright: ignore[reportArgumentType]
    return cast(ExtendedPiezo, _model_at(space, active.full(result.z)))


class _ActiveProblem(eqx.Module):
    """A `Problem` seen through its free coordinates only, padded to a few fixed
    sizes: the Jacobian then costs one tangent per free parameter (not per parameter
    of the space), and fits over different free sets share a compilation."""

    problem: Problem
    base: jax.Array
    index: jax.Array

    @classmethod
    def build(cls, problem, z0, free_index, smallest=8):
        # Few distinct sizes, so that fits over different free sets share one
        # compiled program (each costs seconds to compile; a padded coordinate costs
        # one tangent per Jacobian).
        sizes = [k for k in (8, 11, 14, len(ALL_NAMES)) if k >= smallest]
        size = next(k for k in sizes if k >= len(free_index))
        padding = [len(ALL_NAMES)] * (size - len(free_index))
        return cls(problem, jnp.asarray(z0), jnp.asarray(list(free_index) + padding))

    def full(self, z):
        extended = jnp.concatenate([self.base, jnp.zeros(1, self.base.dtype)])
        return extended.at[self.index].set(z)[:-1]

    def start(self):
        extended = jnp.concatenate([self.base, jnp.zeros(1, self.base.dtype)])
        return extended[self.index]

    def residuals(self, z):
        return self.problem.residuals(self.full(z))

    def rmse(self, z):
        return self.problem.rmse(self.full(z))


def _switch_off(model: ExtendedPiezo, effect: str) -> ExtendedPiezo:
    """`model` with one catalogue effect switched off (its gains at zero)."""
    if effect == "dynamics":
        return dataclasses.replace(model, dynamic=False)
    # Time constants are inert once their gain is zero.
    gains = [p for p in CATALOGUE[effect].parameters if not p.endswith("_time")]
    return model.replace(**{p: 0.0 for p in gains})


def _with_effect(model: ExtendedPiezo, effect: str, source: ExtendedPiezo):
    """`model` with `effect`'s parameters taken from `source`."""
    values = {p: float(getattr(source, p)) for p in CATALOGUE[effect].parameters}
    if effect == "dynamics":
        return model.with_dynamics(values["natural_frequency"], values["damping_ratio"])
    return model.replace(**values)


def _holdout_blocks(n: int, fraction: float, blocks: int = 30) -> np.ndarray:
    """Fit mask that holds out evenly spread blocks (about `fraction` of the samples),
    so that slow effects are judged by interpolation, not extrapolation. Many short
    blocks: every kind of excitation in the record (a sweep, a hold, a fast burst)
    then lands on both sides, so the held-out error measures the physics, not how the
    base model extrapolates to a segment it never saw."""
    held = max(1, round(fraction * blocks))
    chosen = np.round(np.linspace(1, blocks - 1, held)).astype(int)
    edges = np.linspace(0, n, blocks + 1).astype(int)
    mask = np.ones(n, bool)
    for b in chosen:
        mask[edges[b] : edges[b + 1]] = False
    return mask


def _noise_ratio(noise: np.ndarray, coef: np.ndarray, innovation_var: float) -> float:
    """N_eff / N for noise following the AR model: variance over long-run variance."""
    long_run = innovation_var / max(1e-12, (1 - float(np.sum(coef)))) ** 2
    return min(1.0, max(1e-4, float(np.var(noise)) / long_run))


def _mse(residual, mask):
    return float(np.mean(residual[mask] ** 2))


# ---------------------------------------------------------------------- diagnose


def _chi2():
    from scipy import stats  # deferred: scipy.stats costs ~0.5 s of import time

    return stats.chi2


def diagnose(
    recording: Recording,
    *,
    key: PRNGKeyArray,
    base: AbstractHysteresisModel | None = None,
    holdout_fraction: float = 0.3,
    max_effects: int = 3,
    significance: float = 1e-6,
    swarm: MPSO | None = MPSO(num_particles=100, num_iterations=200),
    progress: bool = False,
    device: jax.Device | None = None,
) -> Diagnosis:
    """Find the physics a quasi-static piezo model leaves out of `recording`.

    The base model (`PiezoBoucWen`) is fitted on the first `1 - holdout_fraction` of
    the record (or taken from `base`). Each catalogue effect is scored by a
    Lagrange-multiplier test: the residual's projection on the effect's parameter
    gradients at zero, after removing what the base parameters can absorb, with a
    long-run (Newey-West) variance so that coloured noise does not pass for physics.
    The strongest candidates are refitted (warm start + Levenberg-Marquardt); one is
    adopted only if it lowers the error on the held-out tail by more than its noise
    and lowers an information criterion on the fitted part. Repeats until nothing
    significant is left or `max_effects` are adopted.

    Lower `significance` to be stricter; raise `holdout_fraction` on long records.
    `device`: where the diagnosis runs; None: the host CPU when the default device is
    an accelerator (its refits and Jacobians integrate one trajectory at a time,
    which a CPU runs faster), else the default device.
    """
    if not isinstance(recording, Recording):
        raise TypeError(
            f"diagnose: recording must be a Recording, got {type(recording).__name__}."
        )
    if not 0.05 <= holdout_fraction <= 0.5:
        raise ValueError(
            f"diagnose: holdout_fraction={holdout_fraction} must be in [0.05, 0.5]."
        )
    recording.require_samples(200, what="the diagnosis")
    device = serial_device(device)
    with running_on(device):
        return _diagnose(
            recording,
            moved_to(key, device),
            base=moved_to(base, device),
            holdout_fraction=holdout_fraction,
            max_effects=max_effects,
            significance=significance,
            swarm=swarm,
            progress=progress,
        )


def _diagnose(
    recording: Recording,
    key: PRNGKeyArray,
    *,
    base: AbstractHysteresisModel | None,
    holdout_fraction: float,
    max_effects: int,
    significance: float,
    swarm: MPSO | None,
    progress: bool,
) -> Diagnosis:
    start_time = time.perf_counter()
    inputs = recording.input_path()
    measured = jnp.asarray(recording.y)
    y = np.asarray(recording.y)
    t = np.asarray(recording.t)
    n = y.size
    fit_mask = _holdout_blocks(n, holdout_fraction)
    hold_mask = ~fit_mask
    weights = jnp.asarray(fit_mask, measured.dtype)
    fs = recording.sample_rate
    duration = recording.duration

    if base is None:
        base_fit: Fit = identify(
            PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5),
            recording,
            key=key,
            swarm=swarm,
            weights=weights,
            analyse=False,
            progress=progress,
        )
        base = base_fit.model
    current = ExtendedPiezo.around(base, inputs)
    predicted = _predict(current, inputs)
    base_predicted = predicted
    baseline = error_metrics(y, predicted)
    location = locate(t, np.asarray(recording.u), y - predicted)
    free = list(BASE_FREE)
    findings: list[Finding] = []
    # The other candidates that passed validation in the round an effect was adopted,
    # with where the mismatch was then: revisited once later effects are in.
    runners_up: dict[str, tuple[list[dict[str, Any]], dict[str, Any]]] = {}
    ambiguities: list[str] = []
    rounds: list[list[dict[str, Any]]] = []
    threshold_cache: dict[int, float] = {}
    natural: dict[str, float] = {}

    def refit(model, names, **options):
        """`_refit` on this recording (with the current round's natural scales)."""
        return _refit(
            model, names, inputs, measured, weights, natural, fs, duration, **options
        )

    neff_ratio, noise_sd = 1.0, 0.0
    n_eff_hold = float(hold_mask.sum())

    for _ in range(max_effects):
        residual = y - predicted
        solver = SOLVER
        remaining = [e for e in EFFECT_NAMES if e not in {f.effect for f in findings}]
        static_names = [
            p for e in remaining if e != "dynamics" for p in CATALOGUE[e].parameters
        ]
        jac = _jacobian(current, STATIC_NAMES, inputs, solver)
        column = {name: jac[:, i] for i, name in enumerate(STATIC_NAMES)}
        if current.dynamic:
            dyn = _jacobian(
                current, ("natural_frequency", "damping_ratio"), inputs, solver
            )
            column["natural_frequency"], column["damping_ratio"] = dyn[:, 0], dyn[:, 1]
        base_cols = np.stack([column[p] for p in free], axis=1)
        extra = {name: column[name] for name in static_names}
        w = fit_mask.astype(float)
        projected = {}
        for effect in remaining:
            params = CATALOGUE[effect].parameters
            if effect == "dynamics":
                cols = _dynamics_directions(predicted, float(inputs.dt))
            else:
                cols = np.stack([extra[p] for p in params], axis=1)
            projected[effect] = (cols, _project_off(base_cols, cols, w))
        # The noise's colour, read from what no candidate explains.
        everything = np.concatenate([p for _, p in projected.values()], axis=1)
        coef, *_ = np.linalg.lstsq(everything, residual * w, rcond=None)
        unexplained = (residual * w - everything @ coef)[fit_mask]
        ar = _whitening_filter(unexplained)
        sigma2 = float(np.var(_whiten(unexplained, ar)[len(ar) :]))
        noise_sd = float(np.std(unexplained))
        neff_ratio = _noise_ratio(unexplained, ar, sigma2)
        n_eff_hold = neff_ratio * hold_mask.sum()
        scored = []
        for effect in remaining:
            params = CATALOGUE[effect].parameters
            cols, perp = projected[effect]
            norms = np.linalg.norm(perp, axis=0)
            usable = norms > 1e-9 * (np.linalg.norm(cols, axis=0) + 1e-300)
            if not usable.any():
                continue
            perp = perp[:, usable]
            stat = _score(perp, residual * w, ar, sigma2)
            dof = perp.shape[1]
            if dof not in threshold_cache:
                threshold_cache[dof] = float(_chi2().isf(significance, dof))
            log10_p = float(_chi2().logsf(stat, dof) / np.log(10))
            step, *_ = np.linalg.lstsq(perp, residual * w, rcond=None)
            explained = float(np.sum((perp @ step) ** 2) / max(1, w.sum()))
            scored.append(
                {
                    "effect": effect,
                    "statistic": stat,
                    "dof": dof,
                    "log10_p": log10_p,
                    "explained_mse": explained,
                    "significant": stat > threshold_cache[dof],
                    "step": dict(zip([p for p, ok in zip(params, usable) if ok], step)),
                    "directions": perp,
                }
            )
        scored.sort(key=lambda c: -c["statistic"] / c["dof"])
        # The score test ranks and gates; every significant effect is then refitted
        # from its best starting point, and held-out data decide.
        # Only the strongest few are worth a refit: weaker ones have never won a
        # round on their own (and each refit costs a short swarm plus LM).
        significant = [c for c in scored if c["significant"]]
        candidates = significant[:MAX_REFITS_PER_ROUND]
        # The linearised score understates a resonance (its effect is far from linear
        # in 1/omega^2), so a significant dynamics candidate is always refitted.
        candidates += [
            c for c in significant[MAX_REFITS_PER_ROUND:] if c["effect"] == "dynamics"
        ]
        for cand in candidates:
            cand["start"], cand["start_mse"] = _best_start(
                cand["effect"], current, cand["step"], inputs, y, fit_mask, fs
            )
        round_summary = [
            {k: v for k, v in c.items() if k not in ("directions", "step", "start")}
            for c in scored
        ]
        rounds.append(round_summary)
        if not candidates:
            break
        natural = {}
        rms_y = float(np.sqrt(np.mean(y**2)))
        for p, col in column.items():
            norm = float(np.sqrt(np.mean(col**2)))
            natural[p] = rms_y / norm if norm > 0 else 1.0
        results = []
        for cand in candidates:
            effect = cand["effect"]
            trial = cand["start"]
            names = free + list(CATALOGUE[effect].parameters)
            try:
                refitted = refit(
                    trial,
                    names,
                    max_steps=20,
                    key=jax.random.fold_in(key, 1000 * len(findings) + len(results)),
                )
            except Exception as error:  # a failed candidate is just rejected
                for entry in round_summary:
                    if entry["effect"] == effect:
                        entry["refit_error"] = str(error).splitlines()[0][:200]
                continue
            new_pred = _predict(refitted, inputs)
            if not np.all(np.isfinite(new_pred)):
                for entry in round_summary:
                    if entry["effect"] == effect:
                        entry["refit_error"] = "the refitted model diverged"
                continue
            new_res = y - new_pred
            before_hold, after_hold = (
                _mse(residual, hold_mask),
                _mse(new_res, hold_mask),
            )
            before_fit, after_fit = _mse(residual, fit_mask), _mse(new_res, fit_mask)
            n_eff_fit = neff_ratio * fit_mask.sum()
            change = np.sqrt(np.mean((new_pred - predicted)[hold_mask] ** 2))
            # The held-out MSE drop must beat its own noise, ~2*sigma*rms(change)/sqrt(N_eff),
            # and be worth having (5 % of the MSE): small gains are spurious effects
            # soaking up what an adopted effect's form does not quite capture.
            resolution = _resolution(noise_sd, change, n_eff_hold)
            margin = max(0.05 * before_hold, resolution)
            p = len(CATALOGUE[effect].parameters)
            bic_change = n_eff_fit * math.log(after_fit / before_fit) + p * math.log(
                n_eff_fit
            )
            results.append(
                {
                    "candidate": cand,
                    "model": refitted,
                    "predicted": new_pred,
                    "validation": {
                        "heldout_rmse_before": math.sqrt(before_hold),
                        "heldout_rmse_after": math.sqrt(after_hold),
                        "fit_rmse_before": math.sqrt(before_fit),
                        "fit_rmse_after": math.sqrt(after_fit),
                        "heldout_margin_mse": margin,
                        "heldout_resolution_mse": resolution,
                        "effective_samples_heldout": n_eff_hold,
                        "bic_change": bic_change,
                        "score_statistic": cand["statistic"],
                        "score_dof": cand["dof"],
                        "log10_p": cand["log10_p"],
                        "accepted": bool(
                            before_hold - after_hold > margin and bic_change < 0
                        ),
                    },
                }
            )
        for result in results:
            for entry in round_summary:
                if entry["effect"] == result["candidate"]["effect"]:
                    entry["validation"] = result["validation"]
        accepted = [r for r in results if r["validation"]["accepted"]]
        if not accepted:
            # Signatures compared beyond what the base model's own parameters
            # explain (both sides are largely functions of the input otherwise).
            base_only = np.stack([column[p] for p in BASE_FREE], axis=1)
            adopted = {
                f.effect: _project_off(base_only, _effect_columns(f.effect, column), w)
                for f in findings
            }
            candidates_raw = {
                effect: _project_off(base_only, cols, w)
                for effect, (cols, _) in projected.items()
            }
            ambiguities += _standing_in(results, candidates_raw, adopted)
            break
        accepted.sort(key=lambda r: r["validation"]["heldout_rmse_after"])
        winner = accepted[0]
        effect = winner["candidate"]["effect"]
        for other in accepted[1:]:
            # Ambiguous: the two fits differ on held-out data by less than the
            # held-out comparison can resolve, and their signatures overlap.
            difference = (
                other["validation"]["heldout_rmse_after"] ** 2
                - winner["validation"]["heldout_rmse_after"] ** 2
            )
            apart = np.sqrt(
                np.mean((other["predicted"] - winner["predicted"])[hold_mask] ** 2)
            )
            resolution = _resolution(noise_sd, apart, n_eff_hold)
            overlap = _max_canonical_correlation(
                winner["candidate"]["directions"], other["candidate"]["directions"]
            )
            if difference < resolution and overlap > 0.9:
                ambiguities.append(
                    f"cannot tell {effect} from {other['candidate']['effect']} on this "
                    f"recording: both explain the mismatch about equally (held-out "
                    f"RMSE {winner['validation']['heldout_rmse_after']:.3g} vs "
                    f"{other['validation']['heldout_rmse_after']:.3g}; their "
                    f"signatures overlap, canonical correlation {overlap:.2f}). "
                    "Excite several rates/frequencies (and holds) to separate them; "
                    f"{effect} is kept for the fit."
                )
        where_now = locate(t, np.asarray(recording.u), y - predicted)
        runners_up[effect] = (accepted[1:], where_now)
        before = error_metrics(y, predicted)
        after = error_metrics(y, winner["predicted"])
        findings.append(
            Finding(
                effect,
                _evidence(effect, winner, where_now),
                describe(where_now),
                float(winner["candidate"]["statistic"]),
                {
                    p: float(getattr(winner["model"], p))
                    for p in CATALOGUE[effect].parameters
                },
                before,
                after,
                winner["validation"],
            )
        )
        free = free + [p for p in CATALOGUE[effect].parameters if p not in free]
        # Converge the adopted model before looking for more: an under-fitted
        # winner leaves structure that would pass for a further effect.
        current = refit(winner["model"], free)
        predicted = _predict(current, inputs)
        if not np.all(np.isfinite(predicted)) or _mse(y - predicted, fit_mask) > _mse(
            y - winner["predicted"], fit_mask
        ):
            current, predicted = winner["model"], winner["predicted"]

    # Backward check: an effect adopted early can become redundant once a later one
    # explains the same mismatch with the right form (e.g. a rate dependence that was
    # standing in for an input network). Drop any that no longer earns its place.
    while len(findings) >= 2:
        hold_now = _mse(y - predicted, hold_mask)
        weakest = None
        for finding in findings:
            names = [p for p in free if p not in CATALOGUE[finding.effect].parameters]
            try:
                reduced = refit(
                    _switch_off(current, finding.effect), names, max_steps=20
                )
            except Exception:  # noqa: BLE001 - a failed refit keeps the effect
                continue
            reduced_pred = _predict(reduced, inputs)
            if not np.all(np.isfinite(reduced_pred)):
                continue
            loss = _mse(y - reduced_pred, hold_mask) - hold_now
            change = np.sqrt(np.mean((reduced_pred - predicted)[hold_mask] ** 2))
            needed = max(
                0.05 * _mse(y - reduced_pred, hold_mask),
                _resolution(noise_sd, change, n_eff_hold),
            )
            if loss < needed and (weakest is None or loss < weakest[1]):
                weakest = (finding, loss, reduced, reduced_pred, names)
        if weakest is None:
            break
        finding, _, current, predicted, free = weakest
        findings = [f for f in findings if f is not finding]
        ambiguities.append(
            f"{finding.effect} was adopted, then dropped: once "
            f"{', '.join(f.effect for f in findings)} had been added it no longer "
            "lowered the held-out error by more than its noise."
        )

    # Revisit greedy choices: an effect adopted while a later one was still
    # unmodelled may have won by soaking up part of that one (a time shift standing in
    # for a resonance while the branches' asymmetry was unexplained). With the later
    # effects in the model, each runner-up of its round is tried in its place.
    for position in range(len(findings) - 1):
        finding = findings[position]
        others, where_then = runners_up.get(finding.effect, ([], {}))
        for other in others:
            alternative = other["candidate"]["effect"]
            if alternative in {f.effect for f in findings}:
                continue
            names = [
                p for p in free if p not in CATALOGUE[finding.effect].parameters
            ] + list(CATALOGUE[alternative].parameters)
            trial = _with_effect(
                _switch_off(current, finding.effect), alternative, other["model"]
            )
            try:
                swapped = refit(
                    trial,
                    names,
                    max_steps=20,
                    key=jax.random.fold_in(key, 7919 + position),
                )
            except Exception:  # noqa: BLE001 - a failed refit keeps the adopted effect
                continue
            swapped_pred = _predict(swapped, inputs)
            if not np.all(np.isfinite(swapped_pred)):
                continue
            hold_now = _mse(y - predicted, hold_mask)
            hold_swapped = _mse(y - swapped_pred, hold_mask)
            change = np.sqrt(np.mean((swapped_pred - predicted)[hold_mask] ** 2))
            resolution = _resolution(noise_sd, change, n_eff_hold)
            later = ", ".join(f.effect for f in findings[position + 1 :])
            if hold_now - hold_swapped <= resolution:
                if hold_swapped - hold_now <= resolution:
                    ambiguities.append(
                        f"cannot tell {finding.effect} from {alternative} on this "
                        f"recording: with {later} modelled, either explains the "
                        f"held-out data as well (RMSE {math.sqrt(hold_now):.3g} vs "
                        f"{math.sqrt(hold_swapped):.3g}); {finding.effect} is kept."
                    )
                continue
            ambiguities.append(
                f"{finding.effect} was adopted first, then replaced by {alternative}: "
                f"once {later} had been added, {alternative} explains the held-out "
                f"data better (RMSE {math.sqrt(hold_swapped):.3g} vs "
                f"{math.sqrt(hold_now):.3g}, beyond its noise)."
            )
            findings[position] = Finding(
                alternative,
                _evidence(alternative, other, where_then),
                describe(where_then),
                float(other["candidate"]["statistic"]),
                {
                    p: float(getattr(swapped, p))
                    for p in CATALOGUE[alternative].parameters
                },
                finding.before,
                error_metrics(y, other["predicted"]),
                {**other["validation"], "replaced": finding.effect},
            )
            free = names
            current = refit(swapped, free)
            predicted = _predict(current, inputs)
            if not np.all(np.isfinite(predicted)) or _mse(
                y - predicted, fit_mask
            ) > _mse(y - swapped_pred, fit_mask):
                current, predicted = swapped, swapped_pred
            break

    final_model = current
    if findings:
        # Unit weights rather than None: the same structure as the masked refits,
        # so this fit reuses their compiled Levenberg-Marquardt program.
        all_samples = jnp.ones_like(weights)
        final_model = _refit(
            current, free, inputs, measured, all_samples, {}, fs, duration, max_steps=30
        )
        final_pred = _predict(final_model, inputs)
        if not (
            np.all(np.isfinite(final_pred))
            and _mse(y - final_pred, slice(None)) <= _mse(y - predicted, slice(None))
        ):
            final_model, final_pred = current, predicted
    else:
        final_pred = predicted
    final = error_metrics(y, final_pred)
    final_residual = y - final_pred
    centred = final_residual - final_residual.mean()
    lag1 = float(
        np.dot(centred[:-1], centred[1:]) / max(np.dot(centred, centred), 1e-300)
    )
    noise = {
        "sigma": float(np.sqrt(np.mean(final_residual**2))),
        "lag1_autocorrelation": lag1,
        "effective_samples": effective_samples(final_residual),
    }
    return Diagnosis(
        recording.name,
        n,
        base,
        final_model,
        baseline,
        final,
        findings,
        rounds,
        ambiguities,
        noise["sigma"],
        noise,
        location,
        base_predicted,
        final_pred,
        float(holdout_fraction),
        time.perf_counter() - start_time,
    )


def _evidence(effect: str, winner: dict[str, Any], where: dict[str, Any]) -> str:
    v = winner["validation"]
    gain = 1 - v["heldout_rmse_after"] / v["heldout_rmse_before"]
    words = CATALOGUE[effect].meaning
    specific = {
        "asymmetry": (
            f"mean residual {where['ascending']['mean']:.3g} on the ascending vs "
            f"{where['descending']['mean']:.3g} on the descending branch, and "
            f"{where['extremes']['relative']:.2f}x the overall RMS at the extremes of "
            "the stroke (a bend against the input)"
        ),
        "input_bias": (
            f"residual near reversals is {where['near_reversals']['relative']:.2f}x "
            "the overall RMS, as a time shift of the drive produces"
        ),
        "rate_dependence": (
            f"residual RMS at fast rates is {where['fast_rate']['relative']:.2f}x and at "
            f"slow rates {where['slow_rate']['relative']:.2f}x the overall"
        ),
        "creep": (
            f"residual in the 2 s after holds begin is "
            f"{where['after_hold']['relative']:.2f}x the overall RMS"
            if math.isfinite(where["after_hold"]["relative"])
            else "the recording has no holds, so the slow relaxation shows only as "
            "a lag that grows over seconds after the input's level changes"
        ),
        "dynamics": (
            f"residual dominated by {where['dominant_frequency_hz']:.3g} Hz content and "
            f"fast rates ({where['fast_rate']['relative']:.2f}x)"
        ),
        "drift": (
            f"a slow trend carries {where['slow_trend_rms'] / max(where['overall_rms'], 1e-300):.0%} "
            "of the residual"
        ),
    }[effect]
    return (
        f"{words}. Score test: statistic {v['score_statistic']:.3g} on {v['score_dof']} "
        f"dof (log10 p = {v['log10_p']:.1f}); {specific}. Adding it cut the held-out "
        f"RMSE by {gain:.0%} ({v['heldout_rmse_before']:.3g} -> "
        f"{v['heldout_rmse_after']:.3g})."
    )
