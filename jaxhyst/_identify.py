"""Identify a model from a recording: swarm (MPSO) -> gradient polish -> Fit.

The swarm searches the unit box of a `ParameterSpace` with RK4 steps spanning several
samples (every sample still compared; rate-independent models barely notice the coarser
integration); the polish runs
optimistix Levenberg-Marquardt (or BFGS, or optax Adam) on the full recording from the
swarm's best; identifiability is read off the Jacobian at the result.
"""

import abc
import math
import time
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
import optimistix as optx
from jaxtyping import Array, ArrayLike, Float, PRNGKeyArray

from ._inputs import InputPath
from ._metrics import error_metrics
from ._models.base import AbstractHysteresisModel
from ._params import ParameterSpace
from ._placement import moved_to, running_on, serial_device
from ._recording import Recording
from ._simulate import RK4, AbstractSimulationSolver, simulate, sum_squared_error
from ._stability import is_bibo_stable
from ._swarm import MPSO, SwarmResult, run_swarm


class Problem(eqx.Module):
    """What a fit compares: a parameter space, an input, the measured output."""

    space: ParameterSpace
    inputs: InputPath
    measured: Float[Array, " n"]
    solver: AbstractSimulationSolver
    weights: Float[Array, " n"] | None = None
    stable_only: bool = eqx.field(static=True, default=False)

    def residuals(self, z: Float[Array, " d"]) -> Float[Array, " n"]:
        """Simulated minus measured output, divided by the output scale (and multiplied
        by the weights, e.g. a 0/1 mask that holds data out of the fit)."""
        model = self.space.to_model(z)
        predicted = simulate(model, self.inputs, self.solver, throw=False)
        scale = jnp.max(jnp.abs(self.measured))
        r = (predicted - self.measured) / scale
        return r if self.weights is None else r * self.weights

    def rmse(self, z: Float[Array, " d"]) -> Float[Array, ""]:
        """Root-mean-square error in output units, eq. 12 (+inf for unstable sets when
        `stable_only`), over the weighted samples."""
        model = self.space.to_model(z)
        total = sum_squared_error(
            model, self.inputs, self.measured, self.solver, weights=self.weights
        )
        count = self.measured.size if self.weights is None else jnp.sum(self.weights**2)
        value = jnp.sqrt(total / count)
        if self.stable_only:
            params = model.parameters()
            a = params.get("A1", params.get("A"))
            b = params.get("beta1", params.get("beta"))
            g = params.get("gamma1", params.get("gamma"))
            if a is not None and b is not None and g is not None:
                value = jnp.where(is_bibo_stable(a, b, g, params["n"]), value, jnp.inf)
        return value


def _swarm_objective(z, problem: Problem):
    return problem.rmse(z)


@eqx.filter_jit
def _problem_rmse(problem: Problem, z):
    return problem.rmse(z)


def best_seed(problem: Problem, seeds: list[Array]) -> Array:
    """The starting point with the lowest finite RMSE (the first one if none is
    finite)."""
    scores = [float(_problem_rmse(problem, z)) for z in seeds]
    return seeds[int(np.argmin(np.where(np.isfinite(scores), scores, np.inf)))]


# ----------------------------------------------------------------------------- polish


class PolishResult(eqx.Module):
    """Outcome of a gradient refinement."""

    method: str
    z: Float[Array, " d"]
    loss_history: np.ndarray  # RMSE (output units) after each chunk of steps
    steps: int
    converged: bool
    wall_seconds: float


class AbstractPolish(eqx.Module):
    """A gradient-based refinement of the swarm's best."""

    max_steps: eqx.AbstractVar[int]

    @abc.abstractmethod
    def run(self, problem: Problem, z0: Float[Array, " d"]) -> PolishResult:
        """Refine from `z0`; never returns a worse point than `z0`."""


def _stop_gain(min_gain: float | None, problem: Problem) -> float:
    if min_gain is not None:
        return min_gain
    # The RMSE of n residuals has a relative sampling spread of ~1/sqrt(2n); a gain
    # below 1 % of it changes nothing the data can resolve.
    if problem.weights is None:
        n = problem.measured.size
    else:
        n = int(np.count_nonzero(np.asarray(problem.weights)))
    return max(1e-5, 0.01 / math.sqrt(2 * max(n, 1)))


class AbstractOptimistixPolish(AbstractPolish):
    """An optimistix solver run in chunks of up to 10 steps until it converges, or
    until a chunk lowers the RMSE by less than the fraction `min_gain`. `min_gain =
    None` (default) is 1 % of the RMSE's own sampling spread, 0.01/sqrt(2n) for n
    fitted samples (at least 1e-5): polishing further changes nothing the data can
    resolve. Set it small (1e-12), with tighter `rtol`/`atol`, for noise-free data."""

    min_gain: eqx.AbstractVar[float | None]

    @abc.abstractmethod
    def _advance(self, problem: Problem, z: Array, steps: int) -> tuple[Array, bool]:
        """Take up to `steps` steps from z; return the new z and whether it converged."""

    def run(self, problem: Problem, z0: Float[Array, " d"]) -> PolishResult:
        start = time.perf_counter()
        z = z0
        best_z, best = z0, float(_problem_rmse(problem, z0))
        history = [best]
        taken, converged = 0, False
        chunk = max(1, min(10, self.max_steps))
        enough = _stop_gain(self.min_gain, problem)
        while taken < self.max_steps and not converged:
            z, converged = self._advance(problem, z, chunk)
            taken += chunk
            loss = float(_problem_rmse(problem, z))
            history.append(loss)
            if not np.isfinite(loss):
                break
            converged = converged or loss > best * (1 - enough)
            if loss < best:
                best_z, best = z, loss
        return PolishResult(
            type(self).__name__,
            best_z,
            np.asarray(history),
            taken,
            converged,
            time.perf_counter() - start,
        )


@eqx.filter_jit
def _least_squares(problem, solver, z, steps):
    solution = optx.least_squares(
        lambda z, p: p.residuals(z), solver, z, problem, max_steps=steps, throw=False
    )
    return solution.value, solution.result == optx.RESULTS.successful


@eqx.filter_jit
def _minimise(problem, solver, z, steps):
    solution = optx.minimise(
        lambda z, p: jnp.mean(p.residuals(z) ** 2),
        solver,
        z,
        problem,
        max_steps=steps,
        throw=False,
    )
    return solution.value, solution.result == optx.RESULTS.successful


class LevenbergMarquardtPolish(AbstractOptimistixPolish):
    """optimistix Levenberg-Marquardt on the residuals: the default, and the fastest
    from a swarm's best. Tighten `rtol`/`atol` for noise-free data."""

    rtol: float = 1e-8
    atol: float = 1e-10
    max_steps: int = 100
    min_gain: float | None = None

    def _advance(self, problem, z, steps):
        z, ok = _least_squares(
            problem, optx.LevenbergMarquardt(self.rtol, self.atol), z, steps
        )
        return z, bool(ok)


class BFGSPolish(AbstractOptimistixPolish):
    """optimistix BFGS on the mean squared residual (for comparison with LM)."""

    rtol: float = 1e-8
    atol: float = 1e-10
    max_steps: int = 200
    min_gain: float | None = None

    def _advance(self, problem, z, steps):
        z, ok = _minimise(problem, optx.BFGS(self.rtol, self.atol), z, steps)
        return z, bool(ok)


@eqx.filter_jit
def _adam_steps(problem, z, opt_state, learning_rate, steps):
    optimiser = optax.adam(learning_rate)

    def step(carry, _):
        z, opt_state = carry
        grad = jax.grad(lambda z: jnp.mean(problem.residuals(z) ** 2))(z)
        updates, opt_state = optimiser.update(grad, opt_state)
        return (optax.apply_updates(z, updates), opt_state), None

    (z, opt_state), _ = jax.lax.scan(step, (z, opt_state), None, length=steps)
    return z, opt_state


class AdamPolish(AbstractPolish):
    """optax Adam on the mean squared residual (first-order baseline; slow to
    converge on these ill-conditioned problems, included for comparison)."""

    learning_rate: float = 1e-3
    max_steps: int = 500

    def run(self, problem: Problem, z0: Float[Array, " d"]) -> PolishResult:
        start = time.perf_counter()
        opt_state = optax.adam(self.learning_rate).init(z0)
        z, best_z = z0, z0
        best = float(_problem_rmse(problem, z0))
        history = [best]
        chunk = 50
        taken = 0
        while taken < self.max_steps:
            z, opt_state = _adam_steps(problem, z, opt_state, self.learning_rate, chunk)
            taken += chunk
            loss = float(_problem_rmse(problem, z))
            history.append(loss)
            if np.isfinite(loss) and loss < best:
                best_z, best = jnp.asarray(z), loss
        return PolishResult(
            "AdamPolish",
            best_z,
            np.asarray(history),
            taken,
            False,
            time.perf_counter() - start,
        )


# ---------------------------------------------------------------------- identifiability


class Identifiability(eqx.Module):
    """What the data can and cannot determine, read off the output's Jacobian with
    respect to the *relative* change of every model parameter (d y / d log|theta|).

    - `singular_values`: of the column-scaled Jacobian, largest first, relative to the
      largest.
    - `unidentifiable`: one dict per direction whose relative singular value is below
      `threshold`: parameter name -> weight (a unit vector in relative changes). For
      the piezo model the scaling symmetry shows up as k2 : A1 : beta1 : gamma1 =
      -1 : 1 : (1-n) : (1-n).
    - `correlations`: parameter correlation matrix of the free (fitted) parameters.
    - `standard_errors`: of the free parameters, from sigma^2 (J^T J)^-1 with sigma the
      residual RMS; NaN where the free set is itself not identifiable.
    """

    names: tuple[str, ...]
    singular_values: np.ndarray
    unidentifiable: list[dict[str, float]]
    free_names: tuple[str, ...]
    correlations: np.ndarray
    standard_errors: dict[str, float]
    threshold: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "parameters": list(self.names),
            "relative_singular_values": [float(v) for v in self.singular_values],
            "threshold": self.threshold,
            "unidentifiable_directions": self.unidentifiable,
            "free_parameters": list(self.free_names),
            "standard_errors": self.standard_errors,
            "correlations": [[float(c) for c in row] for row in self.correlations],
        }


@eqx.filter_jit
def _relative_jacobian(model, values, scale, inputs, solver):
    """d y / d log|theta| for every parameter (absolute where theta = 0), and y."""
    names = tuple(model.parameter_names)

    def outputs(relative):
        new = eqx.tree_at(
            lambda m: [getattr(m, n) for n in names],
            model,
            list(values + relative * scale),
        )
        return simulate(new, inputs, solver, throw=False)

    return jax.jacfwd(outputs)(jnp.zeros_like(values)), outputs(jnp.zeros_like(values))


@eqx.filter_jit
def _simulate_quietly(model, inputs, solver):
    return simulate(model, inputs, solver, throw=False)


@eqx.filter_jit
def _model_at(space: ParameterSpace, z):
    """`space.to_model(z)` as one program (eagerly it is a dozen tiny ones)."""
    return space.to_model(z)


def identifiability(
    model: AbstractHysteresisModel,
    inputs: InputPath,
    measured: Float[Array, " n"],
    *,
    free: tuple[str, ...] | None = None,
    solver: AbstractSimulationSolver = RK4(),
    threshold: float = 1e-6,
) -> Identifiability:
    """Identifiability analysis of `model` at its current parameters (see
    `Identifiability`). Parameters equal to zero get an absolute (not relative)
    column. Raise `threshold` to flag directions that are merely poorly determined."""
    names = tuple(model.parameter_names)
    free = names if free is None else tuple(free)
    values = np.array([float(v) for v in model.parameters().values()])
    # Signed scale: column j is d y / d log|theta_j| (an absolute column at zero).
    scale = np.where(values != 0, values, 1.0)

    jac, simulated = _relative_jacobian(model, values, scale, inputs, solver)
    jac = np.nan_to_num(np.asarray(jac))
    norm = np.linalg.norm(jac, axis=0)
    _, sv, vt = np.linalg.svd(jac / np.where(norm > 0, norm, 1.0), full_matrices=False)
    relative = sv / sv[0] if sv[0] > 0 else sv
    null = []
    for s, v in zip(relative, vt):
        if s < threshold:
            v = v / np.where(norm > 0, norm, 1.0)  # back to relative changes
            v = v / v[np.argmax(np.abs(v))]
            null.append(
                {n: round(float(w), 6) for n, w in zip(names, v) if abs(w) > 1e-3}
            )
    residual = np.asarray(simulated) - np.asarray(measured)
    columns = [names.index(n) for n in free]
    jf = jac[:, columns] / np.asarray(scale)[columns]  # d y / d theta (absolute units)
    dof = max(1, residual.size - len(free))
    sigma2 = float(np.sum(residual**2) / dof)
    jtj = jf.T @ jf
    if np.linalg.cond(jtj) < 1e14:
        cov = sigma2 * np.linalg.inv(jtj)
        se = np.sqrt(np.abs(np.diag(cov)))
        corr = cov / np.outer(se, se)
    else:
        se = np.full(len(free), np.nan)
        corr = np.full((len(free), len(free)), np.nan)
    return Identifiability(
        names,
        relative,
        null,
        free,
        corr,
        {n: float(e) for n, e in zip(free, se)},
        threshold,
    )


# ------------------------------------------------------------------------------- fit


class Fit(eqx.Module):
    """The result of `identify`: the fitted model and everything that led to it."""

    model: AbstractHysteresisModel
    predicted: Float[Array, " n"]
    metrics: dict[str, float]
    swarm: SwarmResult | None
    polish: PolishResult | None
    identifiability: Identifiability | None
    timing: dict[str, float]

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready summary (the `jaxhyst fit --json` schema)."""
        out: dict[str, Any] = {
            "model": type(self.model).__name__,
            "parameters": {k: float(v) for k, v in self.model.parameters().items()},
            "metrics": self.metrics,
            "timing": self.timing,
        }
        if self.swarm is not None:
            out["swarm"] = {
                "iterations": self.swarm.iterations_run,
                "evaluations": self.swarm.evaluations,
                "best_rmse": float(self.swarm.best_fitness),
                "stop_reason": self.swarm.stop_reason,
            }
        if self.polish is not None:
            out["polish"] = {
                "method": self.polish.method,
                "steps": self.polish.steps,
                "converged": self.polish.converged,
                "rmse_history": [float(v) for v in self.polish.loss_history],
            }
        out["identifiability"] = (
            self.identifiability.to_dict() if self.identifiability is not None else {}
        )
        return out


def _decimate(problem: Problem, stride: int) -> Problem:
    inputs = problem.inputs
    coarse = InputPath(
        inputs.t0,
        inputs.dt * stride,
        inputs.values[::stride],
        interpolation=inputs.interpolation,
    )
    weights = None if problem.weights is None else problem.weights[::stride]
    return eqx.tree_at(
        lambda p: (p.inputs, p.measured, p.weights),
        problem,
        (coarse, problem.measured[::stride], weights),
        is_leaf=lambda x: x is None,
    )


def _swarm_problem(problem: Problem, stride: int) -> Problem:
    """The swarm's cheaper copy of `problem`: RK4 steps of `stride` samples with dense
    output where the solver and model allow it, else every `stride`-th sample."""
    solver = problem.solver
    if stride == 1:
        return problem
    if (
        isinstance(solver, RK4)
        and solver.substeps == 1
        and solver.samples_per_step == 1
        and problem.space.template.sample_update(problem.inputs) is None
    ):
        return eqx.tree_at(lambda p: p.solver, problem, RK4(samples_per_step=stride))
    return _decimate(problem, stride)


def swarm_samples_per_step(
    u: Float[ArrayLike, " n"],
    *,
    input_fraction: float = 0.01,
    max_steps: int = 2000,
    min_steps: int = 200,
) -> int:
    """How many samples one RK4 step of the swarm's objective spans (`identify`'s
    default `swarm_stride`).

    A rate-independent hysteresis state follows the input's path, so the step is
    set by how far the input moves: as many samples as keep every step's input change
    within `input_fraction` of the input's peak-to-peak range, but no coarser than
    `min_steps` steps over the record. Long records are coarsened further to at most
    `max_steps` steps (the swarm's cost), however fast the input. Lower
    `input_fraction` if swarm and polish disagree on which basin is best.
    """
    u = np.asarray(u, dtype=float)
    if u.ndim != 1 or u.size < 2:
        raise ValueError(
            f"swarm_samples_per_step: u must be 1-D with >= 2 samples, got shape "
            f"{u.shape}."
        )
    intervals = u.size - 1
    span = float(np.ptp(u))
    largest = float(np.max(np.abs(np.diff(u))))
    by_input = intervals if largest == 0 else int(input_fraction * span // largest)
    by_input = min(by_input, intervals // min_steps)
    return max(1, by_input, intervals // max_steps)


def identify(
    model: AbstractHysteresisModel,
    recording: Recording,
    *,
    key: PRNGKeyArray,
    space: ParameterSpace | None = None,
    swarm: MPSO | None = MPSO(num_particles=100, num_iterations=200),
    polish: AbstractPolish | None = LevenbergMarquardtPolish(),
    solver: AbstractSimulationSolver = RK4(),
    swarm_stride: int | None = None,
    stall_iterations: int | None = 40,
    start: AbstractHysteresisModel | None = None,
    stable_only: bool = False,
    weights: Float[Array, " n"] | None = None,
    gauge: bool = True,
    analyse: bool = True,
    progress: bool = False,
    polish_device: jax.Device | None = None,
) -> Fit:
    """Fit `model` (a template: its class, fixed parameters and smoothing) to `recording`.

    - `space`: the free parameters and bounds; default `ParameterSpace.default`, which
      fixes the piezo gauge (A1) unless `gauge=False`.
    - `swarm`: MPSO settings (None skips the swarm and polishes from `start`).
      `MPSO.paper_case(3)` reproduces the paper's schedule (slow; the default finds
      the same basin in a fraction of the time).
    - `swarm_stride`: samples spanned by one RK4 step of the swarm's objective
      (default `swarm_samples_per_step(recording.u)`): the loss landscape of a
      rate-independent model is set by the input's path, not the sample rate. Every
      sample is still compared (dense output, `RK4(samples_per_step=...)`); models
      that `RK4(samples_per_step=...)` cannot run are decimated instead. The polish
      integrates every sample.
    - `start`: a model to polish from (warm start) instead of, or in addition to, the
      swarm's best (the better of the two seeds the polish).
    - `stall_iterations`: stop the swarm when its best has not improved by 1e-4 of the
      output scale for this many iterations (None runs all iterations, as the paper).
    - `stable_only`: give +inf fitness to parameter sets outside Table 2.
    - `weights`: per-sample weights of the loss (a 0/1 mask fits part of the record
      while the model still runs through all of it); metrics are over all samples.
    - `polish_device`: where the polish and everything after it run (one trajectory
      at a time: a sequential scan that a CPU runs faster than a GPU). None: the host
      CPU when the default device is an accelerator, else the default device. The
      swarm runs where `run_swarm` puts it: the default device, or split over all
      visible devices when there are several.
    """
    if not isinstance(recording, Recording):
        raise TypeError(
            f"identify: recording must be a Recording, got {type(recording).__name__}; "
            "use Recording(t, u, y) or Recording.load(path)."
        )
    if swarm is None and start is None:
        raise ValueError("identify: with swarm=None pass start=<model> to polish from.")
    if swarm_stride is not None and (
        not isinstance(swarm_stride, int)
        or isinstance(swarm_stride, bool)
        or swarm_stride < 1
    ):
        raise ValueError(
            f"identify: swarm_stride={swarm_stride!r} must be an integer >= 1 (samples "
            "per RK4 step of the swarm's objective), or None for "
            "swarm_samples_per_step(recording.u)."
        )
    recording.require_samples(20, what="identification")
    device = serial_device(polish_device, "polish_device")
    t_start = time.perf_counter()
    inputs = recording.input_path()
    measured = jnp.asarray(recording.y)
    if space is None:
        space = ParameterSpace.default(
            model,
            float(np.max(np.abs(recording.u))),
            float(np.max(np.abs(recording.y))),
            recording.duration,
            sample_rate=recording.sample_rate,
            gauge=gauge,
        )
    if weights is not None:
        weights = jnp.asarray(weights, measured.dtype)
        if weights.shape != measured.shape:
            raise ValueError(
                f"identify: weights must have one value per sample {measured.shape}, "
                f"got {weights.shape}."
            )
    problem = Problem(space, inputs, measured, solver, weights, stable_only)
    timing: dict[str, float] = {}
    swarm_result = None
    seeds = []
    if swarm is not None:
        stride = swarm_stride or swarm_samples_per_step(recording.u)
        coarse = _swarm_problem(problem, stride)
        swarm_result = run_swarm(
            _swarm_objective,
            jnp.zeros(space.dimension),
            jnp.ones(space.dimension),
            swarm,
            key,
            args=coarse,
            progress=progress,
            chunk_size=20,
            stall_iterations=stall_iterations,
            stall_tolerance=1e-4 * float(np.max(np.abs(recording.y))),
        )
        timing["swarm_s"] = swarm_result.wall_seconds
        seeds.append(swarm_result.best_x)
    if start is not None:
        seeds.append(jnp.clip(space.from_model(start), -0.5, 1.5))
    problem, seeds = moved_to((problem, seeds), device)
    space, inputs, measured = problem.space, problem.inputs, problem.measured
    with running_on(device):
        z = best_seed(problem, seeds)
        polish_result = None
        if polish is not None:
            polish_result = polish.run(problem, z)
            z = polish_result.z
            timing["polish_s"] = polish_result.wall_seconds
        fitted = _model_at(space, z)
        predicted = _simulate_quietly(fitted, inputs, solver)
        metrics = error_metrics(measured, predicted)
        report = None
        if analyse:
            t0 = time.perf_counter()
            report = identifiability(
                fitted, inputs, measured, free=space.names, solver=solver
            )
            timing["identifiability_s"] = time.perf_counter() - t0
    timing["total_s"] = time.perf_counter() - t_start
    return Fit(fitted, predicted, metrics, swarm_result, polish_result, report, timing)
