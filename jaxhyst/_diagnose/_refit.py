"""Refits of the extended model over a subset of its parameters: bounds from the
effects and the record's scales, a short swarm for the basin, then a
Levenberg-Marquardt polish through the padded active problem that lets fits over
different free sets share one compilation, with the effects' additive terms solved
in closed form (variable projection)."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, PRNGKeyArray

from .._identification._polish import LevenbergMarquardtPolish
from .._identification._problem import (
    Problem,
    decimated,
    model_at,
    problem_residuals,
    problem_rmse,
    swarm_objective,
)
from .._inputs import InputPath
from .._models.base import AbstractHysteresisModel
from .._params import ParameterSpace
from .._simulate import AbstractSimulationSolver
from .._swarm import MPSO, run_swarm
from ._effects.base import RefitScales
from ._families import AbstractFamily


def fitted_names(
    family: AbstractFamily, model: AbstractHysteresisModel
) -> tuple[str, ...]:
    """Every parameter of the extended model a refit may move (all but the gauge)."""
    return tuple(n for n in model.parameter_names if n not in family.gauge)


def _usable(bounds: tuple[float, float] | None) -> bool:
    return (
        bounds is not None
        and math.isfinite(bounds[0])
        and math.isfinite(bounds[1])
        and bounds[0] < bounds[1]
    )


def refit_space(
    family: AbstractFamily, model: AbstractHysteresisModel, free, scales: RefitScales
) -> ParameterSpace:
    """One space over all fitted parameters around `model`, with all but `free`
    frozen. Bounds: the effect's own, else the family's, else the current value
    +- its natural scale, else +- twice its size; a rule whose interval is empty or
    not finite (a natural scale below the value's float resolution, from a huge
    sensitivity) gives way to the next."""
    names = fitted_names(family, model)
    owner = {p: e for e in family.catalogue for p in e.parameters}
    bounds = {}
    for name in names:
        value = float(getattr(model, name))
        natural = scales.natural.get(name)
        spread = 2 * abs(value) + 1e-12
        candidates = (
            owner[name].bounds(name, value, scales) if name in owner else None,
            family.base_bounds(name, value),
            None if natural is None else (value - natural, value + natural),
            (value - spread, value + spread),
        )
        bounds[name] = next(b for b in candidates if _usable(b))
    log = [p for e in family.catalogue for p in e.log_scaled if p in names]
    frozen = [n for n in names if n not in free]
    return ParameterSpace(
        model,
        bounds,
        log_scale=log,
        frozen=frozen,
        stable_shape=family.stable_fits,
    )


class DegenerateRefit(Exception):
    """A refit that cannot be carried out at its start: the residuals' sensitivity
    to its closed-form (additive) coordinates is not finite there, or the least
    squares over them fail to converge. The diagnosis rejects the candidate with
    this reason instead of stopping."""


class RefitSettings(eqx.Module):
    """The swarm and polish of one refit."""

    max_steps: int
    swarm: MPSO | None
    # Every how many samples the refit compares (1: all).
    stride: int


def refit(
    family: AbstractFamily,
    model: AbstractHysteresisModel,
    free,
    inputs: InputPath,
    measured: Array,
    weights: Array,
    solver: AbstractSimulationSolver,
    scales: RefitScales,
    settings: RefitSettings,
    *,
    key: PRNGKeyArray | None = None,
) -> AbstractHysteresisModel:
    """Levenberg-Marquardt over `free` (the rest frozen) in one fixed space, on a
    decimated copy when `settings.stride` > 1. With a `key` (and a swarm in the
    settings, and a model without fast linear parts), a short swarm over the same
    space first looks for a better basin: a large effect can pull the base
    parameters far from where the base fit left them. The gains of effects the
    refit leaves off are held at zero meanwhile (`held_at_zero`): their terms are
    not computed."""
    model = model.held_at_zero(idle_gains(family, model, free))
    space = refit_space(family, model, free, scales)
    problem = Problem(space, inputs, measured, solver, weights, family.stable_fits)
    stride = settings.stride
    if stride > 1:
        problem = decimated(problem, stride)
    z0 = space.from_model(model)
    # `inputs` may hold several recordings on a leading axis (a diagnosis over
    # several): lengths and model checks read one record's path.
    length = inputs.values.shape[-1]
    one_record = (
        inputs if inputs.values.ndim == 1 else jax.tree.map(lambda x: x[0], inputs)
    )
    if (
        key is not None
        and settings.swarm is not None
        and not model.has_sample_update(one_record)
    ):
        coarse_stride = max(1, length // 2000)
        coarse = decimated(problem, max(1, coarse_stride // stride))
        swarm = run_swarm(
            swarm_objective,
            jnp.zeros(space.dimension),
            jnp.ones(space.dimension),
            settings.swarm,
            key,
            args=coarse,
            chunk_size=20,
            stall_iterations=20,
            throw=False,
        )
        # A start whose output is not finite loses to any finite swarm best.
        if _finite_or_inf(problem_rmse(problem, swarm.best_x)) < _finite_or_inf(
            problem_rmse(problem, z0)
        ):
            z0 = swarm.best_x
    # Decimated fits (screening, converging, final) come in many free sets and are
    # cheap per step: one padded size for all of them. Full-rate ones (a stage
    # resonance) are expensive per tangent: the tightest size.
    solved = additive_names(family, space, free)
    active = ActiveProblem.build(
        problem,
        z0,
        [space.names.index(n) for n in free if n not in solved],
        smallest=11 if problem.measured.shape[-1] < length else 8,
        additive_index=[space.names.index(n) for n in solved],
        splines=[
            [solved.index(n) for n in effect.smooth]
            for effect in family.catalogue
            if effect.smooth and set(effect.smooth) <= set(solved)
        ],
    )
    z = active.start()
    if len(solved) < len(free):
        polish = LevenbergMarquardtPolish(max_steps=settings.max_steps, min_gain=1e-5)
        # `ActiveProblem` offers the part of `Problem` a polish uses.
        z = polish.run(active, z).z  # pyright: ignore[reportArgumentType]
    # Read off through the space with nothing held (the same values): refits of
    # every held set share the one program of `model_at`.
    released = eqx.tree_at(lambda s: s.template, space, space.template.held_at_zero(()))
    return model_at(released, active.solved(z))


def _finite_or_inf(value) -> float:
    value = float(value)
    return value if math.isfinite(value) else math.inf


def idle_gains(
    family: AbstractFamily, model: AbstractHysteresisModel, free
) -> list[str]:
    """The gains of the catalogue's effects that are zero in `model` and not in
    `free`: what a fit over `free` may hold at zero (`held_at_zero`)."""
    return [
        p
        for effect in family.catalogue
        for p in effect.gains
        if p not in free and float(getattr(model, p)) == 0.0
    ]


def additive_names(
    family: AbstractFamily, space: ParameterSpace, free
) -> tuple[str, ...]:
    """The parameters of `free` that a refit solves in closed form: those the
    catalogue's effects declare `additive`, where the space maps them linearly (no
    log scale, no floor or ceiling), so that the output is affine in their
    coordinates."""
    declared = {p for effect in family.catalogue for p in effect.additive}
    linear = {
        name
        for name, log, floor, ceiling in zip(
            space.names,
            space.log_scale,
            np.asarray(space.floor),
            np.asarray(space.ceiling),
        )
        if not log and np.isneginf(floor) and np.isposinf(ceiling)
    }
    return tuple(n for n in free if n in declared and n in linear)


# How firmly a refit holds a spline's second differences (`AbstractEffect.smooth`)
# at zero: the penalty's weight relative to the mean squared sensitivity of the
# residuals to one coefficient. Measured on the damper suite's six offset-only
# records (the truth's offset plus the record's noise, fitted on the fitted
# samples): without the penalty the offset spline misses the held-out blocks by
# 2.3-22 noise sigmas (a coefficient they leave loose swings); at 1e-3, 1e-2 and
# 1e-1 by 0.17-1.43, 0.21-0.98 and 0.28-0.97 sigma, with 0.06-0.33, 0.08-0.34 and
# 0.15-0.49 sigma left on the fitted samples.
SMOOTHNESS = 1e-2


class ActiveProblem(eqx.Module):
    """A `Problem` seen through its free coordinates only, padded to a few fixed
    sizes: the Jacobian then costs one tangent per free parameter (not per parameter
    of the space), and fits over different free sets share a compilation.

    The `additive` coordinates (parameters that add a fixed function of time to the
    output, such as Legendre drift terms) are not among the free ones: the residuals
    are projected off the directions they move them along, which gives, for any
    value of the free coordinates, the least sum of squares over the additive ones
    (variable projection, exact here because those directions depend on no
    parameter). `solved` then sets them to that least-squares value. A polish thus
    searches fewer coordinates (one tangent each per step) and never has to walk
    the linear ones to their optimum. Additive coordinates that are a spline's
    coefficients (`splines`: positions in `additive`) also carry a penalty on their
    second differences (`SMOOTHNESS`), as rows appended to the residuals: the
    least squares then include it."""

    problem: Problem
    base: jax.Array
    index: jax.Array
    additive: jax.Array
    # The residuals' change per unit of each additive coordinate (m, k), with the
    # penalty's rows below (m + q, k), and an orthonormal basis of the span of
    # those columns (m + q, r); None without any.
    directions: jax.Array | None
    basis: jax.Array | None
    # The penalty's rows at the start (q,): the spline's current second differences;
    # None without a spline among the additive coordinates.
    penalty: jax.Array | None

    @classmethod
    def build(cls, problem, z0, free_index, smallest=8, additive_index=(), splines=()):
        # Few distinct sizes, so that fits over different free sets share one
        # compiled program (each costs seconds to compile; a padded coordinate costs
        # one tangent per Jacobian).
        total = problem.space.dimension
        sizes = [k for k in (8, 11, 14, total) if k >= smallest]
        size = next(k for k in sizes if k >= len(free_index))
        padding = [total] * (size - len(free_index))
        z0 = jnp.asarray(z0)
        additive = jnp.asarray(list(additive_index), dtype=int)
        directions = basis = penalty = None
        if len(additive_index):
            columns = np.asarray(_residual_directions(problem, z0, additive))
            if not np.all(np.isfinite(columns)):
                raise DegenerateRefit(
                    "the output's sensitivity to "
                    + ", ".join(problem.space.names[i] for i in additive_index)
                    + " is not finite at the refit's start"
                )
            rows, start = _spline_penalty(problem.space, z0, additive, columns, splines)
            if rows.shape[0]:
                # Without a spline there is no penalty: the residuals are the problem's.
                columns = np.concatenate([columns, rows])
                penalty = jnp.asarray(start)
            directions = jnp.asarray(columns)
            try:
                left, singular, _ = np.linalg.svd(columns, full_matrices=False)
            except np.linalg.LinAlgError as error:
                raise DegenerateRefit(
                    f"the least squares over the additive terms failed ({error})"
                ) from error
            # Columns that all samples leave at zero (a term the weights mask out
            # entirely) span nothing: drop them rather than project a random
            # direction out.
            keep = singular > 1e-10 * max(float(singular[0]), np.finfo(float).tiny)
            basis = jnp.asarray(left[:, keep])
        return cls(
            problem,
            z0,
            jnp.asarray(list(free_index) + padding),
            additive,
            directions,
            basis,
            penalty,
        )

    def full(self, z):
        extended = jnp.concatenate([self.base, jnp.zeros(1, self.base.dtype)])
        return extended.at[self.index].set(z)[:-1]

    def start(self):
        extended = jnp.concatenate([self.base, jnp.zeros(1, self.base.dtype)])
        return extended[self.index]

    def _with_penalty(self, residuals):
        if self.penalty is None:
            return residuals
        return jnp.concatenate([residuals, self.penalty.astype(residuals.dtype)])

    def residuals(self, z):
        residuals = self.problem.residuals(self.full(z))
        if self.basis is None:
            return residuals
        residuals = self._with_penalty(residuals)
        return residuals - self.basis @ (self.basis.T @ residuals)

    def rmse(self, z):
        full = self.full(z)
        if self.basis is None:
            return self.problem.rmse(full)
        residuals = self.residuals(z)
        weights = self.problem.weights
        samples = self.problem.measured.size
        weight = samples if weights is None else jnp.sum(weights**2)
        squared = jnp.sum(residuals**2)
        value = self.problem.output_scale * jnp.sqrt(squared / weight)
        return self.problem.admissible(full, value)

    def solved(self, z) -> jax.Array:
        """Every coordinate of the space: the free ones from `z`, the additive ones
        at their (penalised) least-squares values given those."""
        full = self.full(z)
        if self.directions is None:
            return full
        residuals = np.asarray(
            self._with_penalty(problem_residuals(self.problem, full))
        )
        if not np.all(np.isfinite(residuals)):
            raise DegenerateRefit("the refitted model's residuals are not finite")
        try:
            step, *_ = np.linalg.lstsq(
                np.asarray(self.directions), -residuals, rcond=None
            )
        except np.linalg.LinAlgError as error:
            raise DegenerateRefit(
                f"the least squares over the additive terms failed ({error})"
            ) from error
        return full.at[self.additive].add(jnp.asarray(step, full.dtype))

    @property
    def fitted_samples(self) -> int:
        return self.problem.fitted_samples


def _spline_penalty(space, z0, additive, columns: np.ndarray, splines):
    """The penalty rows on the additive coordinates (q, k) and their value at `z0`
    (q,): for each spline (positions in `additive`), sqrt(w) times its
    coefficients' second differences, in the parameters' own units (the
    coordinates map to them linearly), w = `SMOOTHNESS` times the mean squared
    residual sensitivity per unit of one coefficient."""
    k = columns.shape[1]
    additive = np.asarray(additive)
    width = np.asarray(space.upper - space.lower)[additive]
    values = np.asarray(space.to_values(z0))[additive]
    rows, start = [], []
    for positions in splines:
        positions = np.asarray(positions)
        if positions.size < 3:
            continue
        per_unit = columns[:, positions] / width[positions]
        weight = math.sqrt(SMOOTHNESS * np.mean(np.sum(per_unit**2, axis=0)))
        second = np.diff(np.eye(positions.size), 2, axis=0) * weight
        block = np.zeros((second.shape[0], k))
        block[:, positions] = second * width[positions]
        rows.append(block)
        start.append(second @ values[positions])
    if not rows:
        return np.zeros((0, k)), np.zeros(0)
    return np.concatenate(rows), np.concatenate(start)


@eqx.filter_jit
def _residual_directions(problem: Problem, z: Array, coordinates: Array) -> Array:
    """The residuals' derivative along each of `coordinates` at `z`, (m, k)."""

    def along(coordinate):
        tangent = jnp.zeros_like(z).at[coordinate].set(1.0)
        return jax.jvp(lambda w: problem.residuals(w), (z,), (tangent,))[1]

    return jax.vmap(along, out_axes=1)(coordinates)
