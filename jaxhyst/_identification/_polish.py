"""Gradient polish of a swarm's best: optimistix Levenberg-Marquardt (default) or
BFGS driven through the solver's own `init`/`step`/`terminate` in one compiled loop
(the solver's damping and trust region persist over the whole polish), plus optax
Adam as a first-order baseline."""

import abc
import math
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array, Float

from .._status import RESULTS, has_status
from ._problem import Problem, problem_residuals, problem_rmse


class PolishResult(eqx.Module):
    """Outcome of a gradient refinement.

    - `z`: the best point found (never worse than the start).
    - `loss_history`: RMSE (output units) at the start and after every `window`
      steps.
    - `steps`: solver steps taken.
    - `result`: a `RESULTS` member: `successful` (converged, or a window gained less
      than `min_gain`), `max_steps_reached`, `nonfinite` (the loss at the start was
      not finite), or `solver_failed`.
    """

    method: str
    z: Float[Array, " d"]
    loss_history: np.ndarray
    steps: int
    result: RESULTS
    wall_seconds: float

    @property
    def converged(self) -> bool:
        """Whether the polish met its stopping rule (`result` is successful)."""
        return has_status(self.result, RESULTS.successful)


class AbstractPolish(eqx.Module):
    """A gradient-based refinement of the swarm's best."""

    max_steps: eqx.AbstractVar[int]

    @abc.abstractmethod
    def run(self, problem: Problem, z0: Float[Array, " d"]) -> PolishResult:
        """Refine from `z0`; never returns a worse point than `z0`."""


def stop_gain(min_gain: float | None, problem: Problem) -> float:
    """The relative RMSE gain per window below which a polish stops: `min_gain`, or
    by default 1 % of the RMSE's own sampling spread, 0.01/sqrt(2n) for n fitted
    samples (at least 1e-5): polishing further changes nothing the data can
    resolve."""
    if min_gain is not None:
        return min_gain
    return max(1e-5, 0.01 / math.sqrt(2 * max(problem.fitted_samples, 1)))


class _Loop(eqx.Module):
    """The carry of the compiled polish loop."""

    z: Array
    state: object
    steps: Array
    window_index: Array
    best_z: Array
    best: Array
    history: Array
    terminate: Array
    stalled: Array
    result: optx.RESULTS


@jax.custom_jvp
def _residuals_jacfwd(z: Array, problem) -> Array:
    """`problem`'s residuals at `z`, whose derivative in `z` is computed as one
    batched forward pass (a tangent per coordinate, carried through the simulation
    together) instead of `jax.linearize`'s stored trajectory replayed per tangent:
    about 7x faster per Levenberg-Marquardt step on a scan-RK4 simulation, and no
    stored trajectory. Differentiates in `z` only (the problem's data are held
    fixed), which is all a polish asks."""
    return problem_residuals(problem, z)


@_residuals_jacfwd.defjvp
def _residuals_jacfwd_jvp(primals, tangents):
    z, problem = primals
    dz, _ = tangents

    def push(direction):
        return jax.jvp(lambda w: problem_residuals(problem, w), (z,), (direction,))

    basis = jnp.eye(z.shape[0], dtype=z.dtype)
    residuals, columns = jax.vmap(push, out_axes=(None, 1))(basis)
    return residuals, columns @ dz


def _objective(least_squares: bool):
    # The jitted forms: traced once, however often the solver's step calls them.
    def residuals(z, problem):
        return _residuals_jacfwd(z, problem), None

    def mean_square(z, problem):
        return jnp.mean(problem_residuals(problem, z) ** 2), None

    return residuals if least_squares else mean_square


def _history_capacity(max_steps: int, window: int) -> int:
    """Room for the start and one RMSE per window of `max_steps` steps, rounded up
    to a power of two of at least 8: polishes of one problem with a different
    number of steps (a candidate's, the converging and the final refit) share one
    program, since `max_steps` itself is a traced value of the loop."""
    windows = -(-max_steps // window)
    return max(8, 1 << windows.bit_length())


@eqx.filter_jit
def _optimistix_loop(
    solver, least_squares, problem, z0, max_steps, window, capacity, min_gain
):
    fn = _objective(least_squares)
    options, tags = {}, frozenset()
    f_struct, aux_struct = jax.eval_shape(lambda: fn(z0, problem))
    state = solver.init(fn, z0, problem, options, f_struct, aux_struct, tags)
    # The loop carries the state's arrays; the rest (e.g. the Jacobian's jaxpr) is
    # fixed across steps, as in optimistix's own loop.
    state, static_state = eqx.partition(state, eqx.is_array)
    history = jnp.full(capacity, jnp.nan)
    no = jnp.array(False)
    # Window -1 takes no step: it scores the start, through the one call of the
    # loss in the program (a second call would compile the simulation again).
    loop = _Loop(
        z0,
        state,
        jnp.array(0),
        jnp.array(-1),
        z0,
        jnp.array(jnp.inf, history.dtype),
        history,
        no,
        no,
        optx.RESULTS.successful,
    )

    def one_step(carry):
        z, dynamic, steps, _, _ = carry
        state = eqx.combine(dynamic, static_state)
        z, state, _ = solver.step(fn, z, problem, options, state, tags)
        terminate, result = solver.terminate(fn, z, problem, options, state, tags)
        return z, eqx.filter(state, eqx.is_array), steps + 1, terminate, result

    def one_window(loop: _Loop) -> _Loop:
        first = loop.window_index < 0
        limit = jnp.where(
            first, loop.steps, jnp.minimum(loop.steps + window, max_steps)
        )

        def keep_stepping(carry):
            _, _, steps, terminate, result = carry
            return (steps < limit) & ~terminate & (result == optx.RESULTS.successful)

        z, state, steps, terminate, result = jax.lax.while_loop(
            keep_stepping,
            one_step,
            (loop.z, loop.state, loop.steps, loop.terminate, loop.result),
        )
        loss = problem_rmse(problem, z)
        better = loss < loop.best
        return _Loop(
            z,
            state,
            steps,
            loop.window_index + 1,
            jnp.where(better, z, loop.best_z),
            jnp.where(better, loss, loop.best),
            loop.history.at[loop.window_index + 1].set(loss),
            terminate,
            # A window that gained, but less than `min_gain`; one with no accepted
            # step (a trust region still shrinking) is not a stall, nor the start.
            ~first & better & ~(loss < loop.best * (1 - min_gain)),
            result,
        )

    def go_on(loop: _Loop):
        return (loop.window_index < 0) | (
            (loop.steps < max_steps)
            & ~loop.terminate
            & ~loop.stalled
            & (loop.result == optx.RESULTS.successful)
            & jnp.isfinite(loop.best)
        )

    loop = jax.lax.while_loop(go_on, one_window, loop)
    status = RESULTS.where(
        loop.result != optx.RESULTS.successful,
        RESULTS.solver_failed,
        RESULTS.where(
            loop.terminate | loop.stalled, RESULTS.successful, RESULTS.max_steps_reached
        ),
    )
    status = RESULTS.where(jnp.isfinite(loop.best), status, RESULTS.nonfinite)
    return loop.best_z, loop.history, loop.window_index, loop.steps, status


def _finished(method, z, history, steps, status, start) -> PolishResult:
    return PolishResult(
        method,
        z,
        np.asarray(history),
        int(steps),
        status,
        time.perf_counter() - start,
    )


class AbstractOptimistixPolish(AbstractPolish):
    """An optimistix solver run from its own `init` through `step`/`terminate` in one
    compiled loop, until it converges, until `max_steps`, or until a window of
    `window` steps lowers the RMSE, but by less than the fraction `min_gain` (a
    window without an accepted step does not stop it).
    `min_gain = None` (default) is 1 % of the RMSE's own sampling spread,
    0.01/sqrt(2n) for n fitted samples (at least 1e-5): polishing further changes
    nothing the data can resolve. Set it small (1e-12), with tighter `rtol`/`atol`,
    for noise-free data."""

    min_gain: eqx.AbstractVar[float | None]
    window: eqx.AbstractVar[int]

    @abc.abstractmethod
    def solver(self) -> optx.AbstractLeastSquaresSolver | optx.AbstractMinimiser:
        """The optimistix solver."""

    @property
    def least_squares(self) -> bool:
        """Whether the solver takes the residual vector (else their mean square)."""
        return isinstance(self.solver(), optx.AbstractLeastSquaresSolver)

    def _loop_arguments(self, problem: Problem, z0: Array) -> tuple:
        window = max(1, min(self.window, self.max_steps))
        return (
            self.solver(),
            self.least_squares,
            problem,
            jnp.asarray(z0),
            np.asarray(self.max_steps),
            window,
            _history_capacity(self.max_steps, window),
            jnp.asarray(stop_gain(self.min_gain, problem), dtype=float),
        )

    def run(self, problem: Problem, z0: Float[Array, " d"]) -> PolishResult:
        start = time.perf_counter()
        z, history, windows, steps, status = _optimistix_loop(
            *self._loop_arguments(problem, z0)
        )
        history = np.asarray(history)[: int(windows) + 1]
        return _finished(type(self).__name__, z, history, steps, status, start)


class LevenbergMarquardtPolish(AbstractOptimistixPolish):
    """optimistix Levenberg-Marquardt on the residuals: the default, and the fastest
    from a swarm's best. Tighten `rtol`/`atol` for noise-free data."""

    rtol: float = 1e-8
    atol: float = 1e-10
    max_steps: int = 100
    min_gain: float | None = None
    window: int = 10

    def solver(self) -> optx.LevenbergMarquardt:
        return optx.LevenbergMarquardt(self.rtol, self.atol)


class BFGSPolish(AbstractOptimistixPolish):
    """optimistix BFGS on the mean squared residual (for comparison with LM)."""

    rtol: float = 1e-8
    atol: float = 1e-10
    max_steps: int = 200
    min_gain: float | None = None
    window: int = 10

    def solver(self) -> optx.BFGS:
        return optx.BFGS(self.rtol, self.atol)


@eqx.filter_jit
def _adam_steps(problem, z, opt_state, learning_rate, steps):
    import optax  # here: only this baseline uses it (importing it takes 0.05 s)

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
    converge on these ill-conditioned problems, included for comparison). It runs a
    fixed schedule of `max_steps`, which counts as successful when its loss is
    finite."""

    learning_rate: float = 1e-3
    max_steps: int = 500
    window: int = 50

    def run(self, problem: Problem, z0: Float[Array, " d"]) -> PolishResult:
        import optax

        start = time.perf_counter()
        opt_state = optax.adam(self.learning_rate).init(z0)
        z, best_z = z0, z0
        best = float(problem_rmse(problem, z0))
        history = [best]
        taken = 0
        while taken < self.max_steps:
            z, opt_state = _adam_steps(
                problem, z, opt_state, self.learning_rate, self.window
            )
            z = jnp.asarray(z)
            taken += self.window
            loss = float(problem_rmse(problem, z))
            history.append(loss)
            if np.isfinite(loss) and loss < best:
                best_z, best = jnp.asarray(z), loss
        status = RESULTS.successful if np.isfinite(best) else RESULTS.nonfinite
        return _finished("AdamPolish", best_z, history, taken, status, start)
