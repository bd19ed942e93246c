"""What a fit compares: `Problem` (the residuals and the swarm's objective over one
recording or several), its cheaper copies for the swarm, and the simulation whose
sensitivities identifiability reads."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.core import Tracer
from jaxtyping import Array, ArrayLike, Float

from .._inputs import InputPath
from .._models.base import AbstractHysteresisModel
from .._params import ParameterSpace
from .._simulate import RK4, AbstractSimulationSolver, simulate, sum_squared_error
from .._stability import is_bibo_stable


def _over_records(function, inputs: InputPath, *arrays):
    """`function(inputs, *arrays)` for one record, vmapped over the leading record
    axis when the problem holds several (stacked, equal-length) records."""
    if inputs.values.ndim == 1:
        return function(inputs, *arrays)
    return jax.vmap(function)(inputs, *arrays)


class Problem(eqx.Module):
    """What a fit compares: a parameter space, an input, the measured output.

    Several recordings fitted with one model are one `Problem` whose `inputs`,
    `measured` and `weights` carry a leading record axis (`stack_problems`): every
    record is simulated from its own initial state, shorter ones padded and masked.
    """

    space: ParameterSpace
    inputs: InputPath
    measured: Float[Array, "*records n"]
    solver: AbstractSimulationSolver
    weights: Float[Array, "*records n"] | None = None
    stable_only: bool = eqx.field(static=True, default=False)

    @property
    def output_scale(self) -> Float[Array, ""]:
        """max |measured| over every record: the residuals' unit. Outside `jit`
        it is computed on the host (no small program compiled per process)."""
        if isinstance(self.measured, Tracer):
            return jnp.max(jnp.abs(self.measured))
        return jnp.asarray(np.max(np.abs(np.asarray(self.measured))))

    @property
    def fitted_samples(self) -> int:
        """How many samples carry weight (all of them without weights)."""
        if self.weights is None:
            return int(self.measured.size)
        return int(np.count_nonzero(np.asarray(self.weights)))

    def simulated(self, model: AbstractHysteresisModel) -> Float[Array, "*records n"]:
        """The model's output at every sample of every record (NaN/inf where it
        diverges)."""
        return _over_records(
            lambda inputs: simulate(model, inputs, self.solver, throw=False),
            self.inputs,
        )

    def residuals(self, z: Float[Array, " d"]) -> Float[Array, " m"]:
        """Simulated minus measured output, divided by the output scale (and multiplied
        by the weights, e.g. a 0/1 mask that holds data out of the fit), flattened
        over records."""
        r = (self.simulated(self.space.to_model(z)) - self.measured) / self.output_scale
        r = r if self.weights is None else r * self.weights
        return r.reshape(-1)

    def rmse(self, z: Float[Array, " d"]) -> Float[Array, ""]:
        """Root-mean-square error in output units, eq. 12, over the weighted samples
        of every record (+inf for sets outside Table 2 when `stable_only`)."""
        model = self.space.to_model(z)

        def total(inputs, measured, weights):
            return sum_squared_error(
                model, inputs, measured, self.solver, weights=weights
            )

        weights = jnp.ones_like(self.measured) if self.weights is None else self.weights
        squared = jnp.sum(_over_records(total, self.inputs, self.measured, weights))
        return self.admissible(z, jnp.sqrt(squared / jnp.sum(weights**2)))

    def admissible(
        self, z: Float[Array, " d"], value: Float[Array, ""]
    ) -> Float[Array, ""]:
        """`value` (a loss at `z`), or +inf when `stable_only` and the model at `z`
        lies outside Table 2's BIBO-stable classes."""
        if not self.stable_only:
            return value
        shape = self.space.to_model(z).bouc_wen_shape()
        stable = is_bibo_stable(shape.A, shape.beta, shape.gamma, shape.n, shape.D)
        return jnp.where(stable, value, jnp.inf)


def stack_problems(problems: list[Problem]) -> Problem:
    """One problem over several recordings of one model: the records' inputs,
    outputs and weights stacked on a leading axis, shorter records padded at the end
    (input held, weight 0) to the longest. All must share the space, solver,
    interpolation and `stable_only`. The residuals are in the unit of the largest
    output, so every sample counts alike in output units."""
    if not problems:
        raise ValueError("stack_problems: need at least one problem.")
    first = problems[0]
    for other in problems[1:]:
        if type(other.solver) is not type(first.solver) or other.solver != first.solver:
            raise ValueError("stack_problems: every record must use the same solver.")
        if other.stable_only != first.stable_only:
            raise ValueError("stack_problems: stable_only differs between records.")
    length = max(p.measured.shape[-1] for p in problems)

    def padded(values, fill):
        values = jnp.asarray(values)
        extra = length - values.shape[-1]
        return jnp.concatenate([values, jnp.full((extra,), fill, values.dtype)])

    def weights(p: Problem):
        w = jnp.ones_like(p.measured) if p.weights is None else p.weights
        return padded(w, 0.0)

    return Problem(
        first.space,
        stack_inputs([p.inputs for p in problems]),
        jnp.stack([padded(p.measured, 0.0) for p in problems]),
        first.solver,
        jnp.stack([weights(p) for p in problems]),
        first.stable_only,
    )


def stack_inputs(paths: list[InputPath]) -> InputPath:
    """Several input paths as one with a leading record axis, shorter ones padded at
    the end to the longest by holding their last value (mask those samples out)."""
    length = max(path.num_samples for path in paths)

    def held(values):
        hold = jnp.repeat(values[..., -1:], length - values.shape[-1], axis=-1)
        return jnp.concatenate([values, hold], axis=-1)

    def padded(path: InputPath) -> InputPath:
        if path.channels is None:
            return eqx.tree_at(lambda i: i.values, path, held(path.values))
        return eqx.tree_at(
            lambda i: (i.values, i.channels),
            path,
            (held(path.values), held(path.channels)),
        )

    return jax.tree.map(lambda *leaves: jnp.stack(leaves), *map(padded, paths))


def swarm_objective(z: Float[Array, " d"], problem: Problem) -> Float[Array, ""]:
    """The swarm's fitness: `problem.rmse(z)` (the `run_swarm` signature)."""
    return problem.rmse(z)


@eqx.filter_jit
def problem_rmse(problem: Problem, z: Float[Array, " d"]) -> Float[Array, ""]:
    """`problem.rmse(z)` as one compiled program. Called inside other programs it
    is traced once per process (JAX caches the trace), not once per call."""
    return problem.rmse(z)


@eqx.filter_jit
def problem_residuals(problem: Problem, z: Float[Array, " d"]) -> Float[Array, " m"]:
    """`problem.residuals(z)`, traced once per process like `problem_rmse`."""
    return problem.residuals(z)


@eqx.filter_jit
def model_at(space: ParameterSpace, z: Float[Array, " d"]) -> AbstractHysteresisModel:
    """`space.to_model(z)` as one program (eagerly it is a dozen tiny ones)."""
    return space.to_model(z)


def best_seed(problem: Problem, seeds: list[Array]) -> Array:
    """The starting point with the lowest finite RMSE (the first one if none is
    finite; a single seed is returned without being scored)."""
    if len(seeds) == 1:
        return seeds[0]
    scores = [float(problem_rmse(problem, z)) for z in seeds]
    return seeds[int(np.argmin(np.where(np.isfinite(scores), scores, np.inf)))]


def decimated(problem: Problem, stride: int) -> Problem:
    """Every `stride`-th sample of `problem` (the input read at the coarser rate)."""
    inputs = problem.inputs
    coarse = eqx.tree_at(
        lambda i: (i.dt, i.values),
        inputs,
        (inputs.dt * stride, inputs.values[..., ::stride]),
    )
    if inputs.channels is not None:
        coarse = eqx.tree_at(
            lambda i: i.channels, coarse, inputs.channels[..., ::stride]
        )
    weights = None if problem.weights is None else problem.weights[..., ::stride]
    return eqx.tree_at(
        lambda p: (p.inputs, p.measured, p.weights),
        problem,
        (coarse, problem.measured[..., ::stride], weights),
        is_leaf=lambda x: x is None,
    )


def swarm_problem(problem: Problem, stride: int) -> Problem:
    """The swarm's cheaper copy of `problem`: RK4 steps of `stride` samples with dense
    output where the solver and model allow it, else every `stride`-th sample."""
    solver = problem.solver
    if stride == 1:
        return problem
    one_record = (
        jax.tree.map(lambda x: x[0], problem.inputs)
        if problem.measured.ndim > 1
        else problem.inputs
    )
    if (
        isinstance(solver, RK4)
        and solver.substeps == 1
        and solver.samples_per_step == 1
        and not problem.space.template.has_sample_update(one_record)
    ):
        return eqx.tree_at(lambda p: p.solver, problem, RK4(samples_per_step=stride))
    return decimated(problem, stride)


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


class RecordSimulation(eqx.Module):
    """A model's output at every sample of one input path: `RecordSimulation(inputs,
    solver)(model)`. A module, so compiled callers (`output_jacobian`) reuse their
    compilation across calls."""

    inputs: InputPath
    solver: AbstractSimulationSolver = RK4()

    def __call__(self, model: AbstractHysteresisModel) -> Float[Array, " n"]:
        return simulate(model, self.inputs, self.solver, throw=False)
