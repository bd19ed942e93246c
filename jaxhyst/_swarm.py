"""Modified particle swarm optimisation (MPSO): Shi & Eberhart inertia-weight PSO with
bounds, velocity clamping and a linearly decreasing inertia weight (paper eq. 9-14).

The optimiser is generic: it minimises any JAX function `objective(x, args) -> scalar`
over a box `lower <= x <= upper`. The pieces are

- `MPSO`: the settings (sizes static, coefficients traced) with `init` / `step`, in
  the shape of an optimistix iterative solver;
- `SwarmState`: the state they pass around;
- `run_swarm`: the driver, a jitted `lax.scan` over chunks of iterations with early
  stopping, progress output and particle sharding across devices between chunks;
- `SwarmResult`: what `run_swarm` returns, with a `RESULTS` status (`result`).
"""

import dataclasses
import sys
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any, Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec
from jaxtyping import Array, ArrayLike, Float, Int, PRNGKeyArray

from ._status import RESULTS, raise_unless_successful


# Table 3 of the paper: case -> (swarm size, number of iterations G).
_PAPER_CASES = {1: (50, 500), 2: (100, 1500), 3: (300, 5000), 4: (500, 10000)}

# Stop codes computed on device; `_STOP_REASONS` maps them to `SwarmResult.stop_reason`.
_RUNNING, _MAX_ITERATIONS, _TARGET, _STALL = 0, 1, 2, 3
StopReason = Literal["max_iterations", "target", "stall"]
_STOP_REASONS: dict[int, StopReason] = {
    _MAX_ITERATIONS: "max_iterations",
    _TARGET: "target",
    _STALL: "stall",
}
_NEVER = np.iinfo(np.int32).max

# Sharded, each device's particle rows are padded to a multiple of this: whole
# 8-lane vectors (float64 AVX-512), so no particle runs in a scalar remainder loop.
_ROWS_MULTIPLE = 8

# Fields of `SwarmState` that carry a leading particle axis (sharded across devices).
_PARTICLE_FIELDS = ("positions", "velocities", "fitness", "pbest", "pbest_fitness")


def _default_float():
    return jax.dtypes.canonicalize_dtype(jnp.float64)


def _coefficient(x):
    """A traced setting as stored: a JAX array (or tracer) in the default float type;
    a Python or NumPy number as a float64 NumPy array, which JAX converts when a
    program is called, at the precision then in force. So a default built at import
    time (`identify`'s `swarm=MPSO(...)`) does not fix its precision before the
    user turns 64-bit floats on."""
    if isinstance(x, jax.Array):  # tracers too
        return jnp.asarray(x, _default_float())
    return np.asarray(x, np.float64)


def _concrete(x) -> np.ndarray | None:
    """`x` as a NumPy array, or None when it is traced (checks are then skipped)."""
    try:
        return np.asarray(x)
    except jax.errors.TracerArrayConversionError:
        return None


def _is_int(x) -> bool:
    return isinstance(x, int | np.integer) and not isinstance(x, bool)


class SwarmState(eqx.Module):
    """State of a swarm between iterations.

    Arrays with a leading particle axis have as many rows as the swarm has particles
    (`run_swarm` may pad them internally for sharding; the state it returns is not
    padded).

    **Fields:**

    - `positions`, `velocities`: `(particles, d)` current positions and velocities.
    - `fitness`: `(particles,)` objective at `positions`; non-finite values are +inf.
    - `pbest`, `pbest_fitness`: each particle's best position and its fitness.
    - `gbest`, `gbest_fitness`: the swarm's best position and its fitness.
    - `iteration`: number of `step`s taken since `init` (`k` in eq. 13).
    - `lower`, `upper`: `(d,)` search box.
    """

    positions: Float[Array, "particles d"]
    velocities: Float[Array, "particles d"]
    fitness: Float[Array, " particles"]
    pbest: Float[Array, "particles d"]
    pbest_fitness: Float[Array, " particles"]
    gbest: Float[Array, " d"]
    gbest_fitness: Float[Array, ""]
    iteration: Int[Array, ""]
    lower: Float[Array, " d"]
    upper: Float[Array, " d"]


def _bounds(lower, upper) -> tuple[Array, Array]:
    lower = jnp.asarray(lower)
    upper = jnp.asarray(upper)
    if lower.ndim != 1 or lower.shape != upper.shape or lower.shape[0] == 0:
        raise ValueError(
            "`lower` and `upper` must be 1-D arrays of the same non-zero length, got "
            f"shapes {lower.shape} and {upper.shape}."
        )
    dtype = jnp.result_type(lower, upper)
    if not jnp.issubdtype(dtype, jnp.floating):
        dtype = _default_float()
    lower, upper = lower.astype(dtype), upper.astype(dtype)
    lo, hi = _concrete(lower), _concrete(upper)
    if lo is not None and hi is not None:
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
            raise ValueError("`lower` and `upper` must be finite.")
        if not np.all(lo < hi):
            bad = np.flatnonzero(~(lo < hi)).tolist()
            raise ValueError(f"Need `lower < upper` in every dimension; not in {bad}.")
    return lower, upper


def _quick_threefry():
    """The swarm's random draws use JAX's non-partitionable threefry: on CPU, XLA
    compiles a partitionable draw of a few thousand numbers ~5x slower (about 1 s per
    draw, measured), and these arrays are small and replicated anyway. The values do
    not depend on sharding either way; the choice is scoped to these draws."""
    return jax.threefry_partitionable(False)


def _fold_in(key, data):
    with _quick_threefry():
        return jr.fold_in(key, data)


def _evaluate(objective, positions, args, valid=None) -> Array:
    """Fitness of every particle; non-finite (and invalid, i.e. padding) -> +inf."""
    values = jnp.asarray(jax.vmap(objective, in_axes=(0, None))(positions, args))
    if values.shape != positions.shape[:1]:
        raise ValueError(
            "`objective(x, args)` must return a scalar; vmapped over the particles it "
            f"returned shape {values.shape} instead of {positions.shape[:1]}."
        )
    values = values.astype(positions.dtype)
    ok = jnp.isfinite(values)
    if valid is not None:
        ok = ok & valid
    return jnp.where(ok, values, jnp.inf)


class MPSO(eqx.Module):
    """Modified particle swarm optimisation (inertia-weight PSO, paper eq. 9-14).

    Each iteration ("Step 8" of the paper):

        v <- w(k) v + c1 r1 (pbest - x) + c2 r2 (gbest - x)     (9), r1, r2 ~ U[0, 1]
        v <- clip(v, -velocity_limit, velocity_limit)                 per dimension
        x <- clip(x + v, lower, upper)                            (10)
        pbest, gbest updated on strict improvement                (11)
        w(k) = w_max - (k / G) (w_max - w_min)                    (13)

    with `k` the number of iterations already taken (so the first step uses `w_max`)
    and `G = num_iterations`; beyond `G`, `w` stays at `w_min`. A particle that hits a
    wall stops there: the velocity component that was clipped is set to **zero**
    (absorbing wall), so it does not keep pushing against the bound.

    **Fields:**

    - `num_particles`, `num_iterations`: static Python ints (changing them recompiles).
    - `c1`, `c2`: cognitive and social coefficients (traced).
    - `w_max`, `w_min`: inertia-weight schedule (traced).
    - `velocity_limit`: a scalar or one value per dimension, in the units of the search
      space (traced). The default 0.2 suits a search in a scaled unit box; the paper
      uses 1.0 on its raw bounds (`MPSO.paper_case`). Change it when searching raw
      paper bounds.

    Traced fields are stored as arrays, so sweeping them does not recompile
    `run_swarm`: numbers as float64 NumPy arrays, which take the precision in force
    when the swarm runs (a swarm built before 64-bit floats are turned on searches as
    one built after), JAX arrays as they are.
    """

    num_particles: int = eqx.field(default=64, static=True)
    num_iterations: int = eqx.field(default=500, static=True)
    c1: Float[Array | np.ndarray, ""] = eqx.field(default=1.3, converter=_coefficient)
    c2: Float[Array | np.ndarray, ""] = eqx.field(default=1.7, converter=_coefficient)
    w_max: Float[Array | np.ndarray, ""] = eqx.field(
        default=0.9, converter=_coefficient
    )
    w_min: Float[Array | np.ndarray, ""] = eqx.field(
        default=0.1, converter=_coefficient
    )
    velocity_limit: Float[Array | np.ndarray, "*d"] = eqx.field(
        default=0.2, converter=_coefficient
    )

    def __check_init__(self):
        if not _is_int(self.num_particles) or self.num_particles < 2:
            raise ValueError(
                f"`num_particles` must be an int >= 2, got {self.num_particles!r}."
            )
        if not _is_int(self.num_iterations) or self.num_iterations < 1:
            raise ValueError(
                f"`num_iterations` must be an int >= 1, got {self.num_iterations!r}."
            )
        for name in ("c1", "c2", "w_max", "w_min"):
            value = getattr(self, name)
            if value.ndim != 0:
                raise ValueError(f"`{name}` must be a scalar, got shape {value.shape}.")
            concrete = _concrete(value)
            if concrete is not None and not (np.isfinite(concrete) and concrete >= 0):
                raise ValueError(f"`{name}` must be finite and >= 0, got {concrete}.")
        w_max, w_min = _concrete(self.w_max), _concrete(self.w_min)
        if w_max is not None and w_min is not None and w_min > w_max:
            raise ValueError(f"Need `w_min <= w_max`, got {w_min} > {w_max}.")
        if self.velocity_limit.ndim > 1:
            raise ValueError(
                "`velocity_limit` must be a scalar or a 1-D array (one per dimension), "
                f"got shape {self.velocity_limit.shape}."
            )
        vlim = _concrete(self.velocity_limit)
        if vlim is not None and not np.all(np.isfinite(vlim) & (vlim > 0)):
            raise ValueError(f"`velocity_limit` must be finite and > 0, got {vlim}.")

    @classmethod
    def paper_case(cls, case: int, **overrides) -> "MPSO":
        """The settings of Table 3, case 1-4: swarm size 50/100/300/500, G
        500/1500/5000/10000, c1 = 1.3, c2 = 1.7, w from 0.9 to 0.1 and velocities in
        [-1, 1] (raw paper units). Keyword `overrides` replace any field, e.g.
        `velocity_limit=0.2` for a search in a scaled unit box."""
        if case not in _PAPER_CASES:
            raise ValueError(
                f"`case` must be one of 1, 2, 3, 4 (Table 3), got {case!r}."
            )
        size, iterations = _PAPER_CASES[case]
        kwargs: dict[str, Any] = dict(
            num_particles=size,
            num_iterations=iterations,
            c1=1.3,
            c2=1.7,
            w_max=0.9,
            w_min=0.1,
            velocity_limit=1.0,
        )
        kwargs.update(overrides)
        return cls(**kwargs)

    def inertia_weight(self, iteration: Int[ArrayLike, ""]) -> Float[Array, ""]:
        """Eq. 13, `w(k) = w_max - (k/G)(w_max - w_min)`, held at `w_min` for k > G."""
        w_max, w_min = jnp.asarray(self.w_max), jnp.asarray(self.w_min)
        fraction = jnp.clip(
            jnp.asarray(iteration, w_max.dtype) / self.num_iterations, 0.0, 1.0
        )
        return w_max - fraction * (w_max - w_min)

    def _velocity_limit(self, d: int, dtype) -> Float[Array, " d"]:
        vlim = jnp.asarray(self.velocity_limit).astype(dtype)
        if vlim.ndim == 1 and vlim.shape[0] != d:
            raise ValueError(
                f"`velocity_limit` has {vlim.shape[0]} entries but the search space "
                f"has {d} dimensions."
            )
        return jnp.broadcast_to(vlim, (d,))

    def init(
        self,
        objective: Callable[[Array, Any], ArrayLike],
        lower: Float[ArrayLike, " d"],
        upper: Float[ArrayLike, " d"],
        key: PRNGKeyArray,
        args: Any = None,
    ) -> SwarmState:
        """Eq. 14: positions uniform in `[lower, upper]`, velocities uniform in
        `[-velocity_limit, velocity_limit]`; evaluate; pbest = positions, gbest their
        best. `objective(x, args)` maps a `(d,)` position to a scalar."""
        state = self._sample(lower, upper, key)
        return self._update(objective, state, state.positions, state.velocities, args)

    def _sample(self, lower, upper, key) -> SwarmState:
        """Eq. 14 without the evaluation: every fitness +inf and `iteration = -1`, so
        that the next `_advance` evaluates these positions instead of moving."""
        lower, upper = _bounds(lower, upper)
        d, dtype = lower.shape[0], lower.dtype
        vlim = self._velocity_limit(d, dtype)
        shape = (self.num_particles, d)
        with _quick_threefry():
            unit = jr.uniform(key, (2, *shape), dtype)
        positions = lower[None] + (upper - lower)[None] * unit[0]
        positions = jnp.clip(positions, lower[None], upper[None])
        velocities = -vlim[None] + 2 * vlim[None] * unit[1]
        unknown = jnp.full((self.num_particles,), jnp.inf, dtype)
        return SwarmState(
            positions=positions,
            velocities=velocities,
            fitness=unknown,
            pbest=positions,
            pbest_fitness=unknown,
            gbest=positions[0],
            gbest_fitness=unknown[0],
            iteration=jnp.asarray(-1, dtype=jnp.int32),
            lower=lower,
            upper=upper,
        )

    def step(
        self,
        objective: Callable[[Array, Any], ArrayLike],
        state: SwarmState,
        key: PRNGKeyArray,
        args: Any = None,
    ) -> SwarmState:
        """One MPSO iteration (eq. 9-11, 13 and the bound handling of Step 8).

        If the state has more rows than `num_particles` (padding added by
        `run_swarm` for sharding) the extra rows are inert: they get zero random
        factors, never move and their fitness is +inf.
        """
        x, v = self._move(state, key)
        return self._update(objective, state, x, v, args)

    def _advance(self, objective, state: SwarmState, key, args) -> SwarmState:
        """`step`, or, on a state from `_sample` (`iteration = -1`), the evaluation
        that completes `init`: one program serves both, so a run compiles the
        objective once."""
        x, v = self._move(state, key)
        fresh = state.iteration < 0
        x = jnp.where(fresh, state.positions, x)
        v = jnp.where(fresh, state.velocities, v)
        return self._update(objective, state, x, v, args)

    def _move(self, state: SwarmState, key) -> tuple[Array, Array]:
        x, v = state.positions, state.velocities
        rows, d = x.shape
        n = self.num_particles
        if rows < n:
            raise ValueError(
                f"The state has {rows} particles but `num_particles` is {n}; create it "
                "with this solver's `init`."
            )
        dtype = x.dtype
        c1, c2 = jnp.asarray(self.c1).astype(dtype), jnp.asarray(self.c2).astype(dtype)
        w = self.inertia_weight(jnp.maximum(state.iteration, 0)).astype(dtype)
        vlim = self._velocity_limit(d, dtype)[None]
        # Random factors are drawn for the real swarm only, so their values do not
        # depend on padding or on how the particles are split across devices.
        with _quick_threefry():
            r = jr.uniform(key, (2, n, d), dtype)
        if rows > n:
            r = jnp.pad(r, ((0, 0), (0, rows - n), (0, 0)))
        v = w * v + c1 * r[0] * (state.pbest - x) + c2 * r[1] * (state.gbest[None] - x)
        v = jnp.clip(v, -vlim, vlim)
        moved = x + v
        x = jnp.clip(moved, state.lower[None], state.upper[None])
        v = jnp.where(moved == x, v, 0)  # absorbing wall: stop the clipped component
        return x, v

    def _update(self, objective, state: SwarmState, x, v, args) -> SwarmState:
        """Evaluate `x` and update the personal and global bests (eq. 11)."""
        rows = x.shape[0]
        valid = (
            jnp.arange(rows) < self.num_particles if rows > self.num_particles else None
        )
        fitness = _evaluate(objective, x, args, valid)
        improved = fitness < state.pbest_fitness
        pbest = jnp.where(improved[:, None], x, state.pbest)
        pbest_fitness = jnp.where(improved, fitness, state.pbest_fitness)
        best = jnp.argmin(pbest_fitness)
        return SwarmState(
            positions=x,
            velocities=v,
            fitness=fitness,
            pbest=pbest,
            pbest_fitness=pbest_fitness,
            gbest=pbest[best],
            gbest_fitness=pbest_fitness[best],
            iteration=state.iteration + 1,
            lower=state.lower,
            upper=state.upper,
        )


class SwarmResult(eqx.Module):
    """What `run_swarm` returns.

    **Fields:**

    - `best_x`: `(d,)` best position found.
    - `best_fitness`: its objective value (+inf if the objective was never finite).
    - `history`: NumPy array of length `iterations_run + 1`; `history[k]` is the best
      fitness after `k` iterations (`history[0]` is the initial swarm).
    - `iterations_run`: MPSO iterations taken.
    - `evaluations`: objective evaluations, `num_particles * (iterations_run + 1)`.
    - `wall_seconds`: total time of the call, compilation included.
    - `compile_seconds`: time JAX spent tracing, lowering and compiling during the call
      (0 when everything was cached; approximate if other threads compile meanwhile).
    - `stop_reason`: *why* the run stopped: `"target"` (the best fitness reached
      `target`), `"stall"` (no improvement by more than `stall_tolerance` for
      `stall_iterations` iterations) or `"max_iterations"` (the schedule of
      `num_iterations` ran out). When several hold at the same iteration the first
      of target, stall, max_iterations is given.
    - `result`: *whether* that is a success, a `RESULTS` item:
        - `RESULTS.successful`: the stopping rule was met: the target was reached
          or the swarm stalled; or, with neither `target` nor `stall_iterations`
          set (a fixed schedule, as in the paper), the schedule ran to its end.
        - `RESULTS.max_steps_reached`: an early-stopping rule (`target` and/or
          `stall_iterations`) was set, but the iterations ran out before it was
          met (`stop_reason == "max_iterations"`).
        - `RESULTS.nonfinite`: the best fitness is not finite (the objective was
          never finite at any particle); this takes precedence over the others.

      `status_name(result.result)` gives the member's name as a string.
    - `state`: the final `SwarmState` (e.g. for the pbest of every particle).
    """

    best_x: Float[Array, " d"]
    best_fitness: float
    history: np.ndarray
    iterations_run: int
    evaluations: int
    wall_seconds: float
    compile_seconds: float
    stop_reason: StopReason
    result: RESULTS
    state: SwarmState


class _Monitor(eqx.Module):
    """Early-stopping bookkeeping carried through the scan."""

    reference: Float[Array, ""]  # best fitness at the last improvement
    last_improvement: Int[Array, ""]  # iteration of the last improvement


def _stop_code(swarm, state, monitor, target, stall_iterations) -> Int[Array, ""]:
    # A met stopping rule takes precedence over the end of the schedule, so a run
    # that stalls (or reaches its target) on its last iteration counts as a success.
    return jnp.where(
        state.gbest_fitness <= target,
        _TARGET,
        jnp.where(
            state.iteration - monitor.last_improvement >= stall_iterations,
            _STALL,
            jnp.where(
                state.iteration >= swarm.num_iterations, _MAX_ITERATIONS, _RUNNING
            ),
        ),
    )


def _status(code: int, best_fitness: float, early_stopping: bool) -> RESULTS:
    """The `RESULTS` item of a finished run (host side, see `SwarmResult`)."""
    if not np.isfinite(best_fitness):
        return RESULTS.nonfinite
    if code == _MAX_ITERATIONS and early_stopping:
        return RESULTS.max_steps_reached
    return RESULTS.successful


def _map_state(state: SwarmState, fn, particle, replicated) -> SwarmState:
    """Apply `fn(array, sharding)` to every field: particle fields get `particle`."""
    changes = {}
    for field in dataclasses.fields(state):
        value = getattr(state, field.name)
        kind = particle if field.name in _PARTICLE_FIELDS else replicated
        changes[field.name] = fn(value, kind)
    return SwarmState(**changes)


# `iteration` of a state whose positions are still to be drawn (`_unsampled`).
_UNSAMPLED = -2


def _unsampled(swarm: MPSO, lower: Array, upper: Array) -> SwarmState:
    """The state `run_swarm` starts from: the shapes of `swarm._sample`'s, made on
    the host (NumPy arrays given their dtype: `jnp.asarray` compiles nothing), with
    `iteration = _UNSAMPLED`; the first chunk draws the positions (eq. 14) in its own
    program, so that a run compiles no program of its own for them."""
    dtype = np.dtype(lower.dtype)
    rows = jnp.asarray(np.zeros((swarm.num_particles, lower.shape[0]), dtype), dtype)
    unknown = jnp.asarray(np.full((swarm.num_particles,), np.inf, dtype), dtype)
    return SwarmState(
        positions=rows,
        velocities=rows,
        fitness=unknown,
        pbest=rows,
        pbest_fitness=unknown,
        gbest=jnp.asarray(np.zeros(lower.shape[0], dtype), dtype),
        gbest_fitness=jnp.asarray(np.asarray(np.inf, dtype), dtype),
        iteration=jnp.asarray(np.asarray(_UNSAMPLED, np.int32), jnp.int32),
        lower=lower,
        upper=upper,
    )


@eqx.filter_jit
def _run_chunk(
    swarm: MPSO,
    objective,
    state: SwarmState,
    monitor: _Monitor,
    key,
    args,
    target,
    stall_iterations,
    stall_tolerance,
    length: int,
    particle_sharding,
    replicated_sharding,
):
    """`length` MPSO iterations in one `lax.scan`. Once a stop condition holds the
    state is frozen (a `lax.cond`: the remaining passes of the chunk skip the
    objective), so where a run stops does not depend on the chunk length. A state
    from `_unsampled` gets its positions drawn first, from the first half of `key`
    (the iterations' keys fold the second half with the iteration)."""
    with _quick_threefry():
        key_init, key_loop = jr.split(key)

    def constrain(tree):
        if particle_sharding is None:
            return tree
        return _map_state(
            tree,
            jax.lax.with_sharding_constraint,
            particle_sharding,
            replicated_sharding,
        )

    def advance(carry):
        state, monitor = carry
        new = constrain(
            swarm._advance(objective, state, _fold_in(key_loop, state.iteration), args)
        )
        improved = new.gbest_fitness < monitor.reference - stall_tolerance
        new_monitor = _Monitor(
            reference=jnp.where(improved, new.gbest_fitness, monitor.reference),
            last_improvement=jnp.where(
                improved, new.iteration, monitor.last_improvement
            ),
        )
        return new, new_monitor

    def body(carry, _):
        state, monitor = carry
        running = (
            _stop_code(swarm, state, monitor, target, stall_iterations) == _RUNNING
        )
        state, monitor = jax.lax.cond(running, advance, lambda c: c, carry)
        return (state, monitor), state.gbest_fitness

    def draw(state):
        # Eq. 14's positions, padded as `state` is (the pads inert).
        rows = state.positions.shape[0]
        return _pad_state(swarm._sample(state.lower, state.upper, key_init), rows)

    state = jax.lax.cond(state.iteration == _UNSAMPLED, draw, lambda s: s, state)
    (state, monitor), history = jax.lax.scan(
        body, (constrain(state), monitor), length=length
    )
    code = _stop_code(swarm, state, monitor, target, stall_iterations)
    return state, monitor, history, code


class _CompileTimer:
    """Sums JAX's tracing/lowering/compilation durations in this thread while
    registered (the listener hears every thread's: `identify` compiles its polish in
    another while the swarm runs, and a diagnosis runs swarms side by side)."""

    def __init__(self):
        self.seconds = 0.0
        self._thread = threading.get_ident()

    def __call__(self, event: str, duration_secs: float, **kwargs: str | int) -> None:
        if event.startswith("/jax/core/compile/") and (
            threading.get_ident() == self._thread
        ):
            self.seconds += duration_secs

    def __enter__(self):
        jax.monitoring.register_event_duration_secs_listener(self)
        return self

    def __exit__(self, *exc):
        jax.monitoring.unregister_event_duration_listener(self)


def _progress(iteration, total, best, elapsed) -> None:
    width = 24
    filled = int(width * min(iteration / total, 1.0))
    bar = "#" * filled + "." * (width - filled)
    line = f"\rMPSO [{bar}] {iteration}/{total}  best {best:.6e}  {elapsed:.1f} s   "
    sys.stderr.write(line)
    sys.stderr.flush()


def _pad_state(state: SwarmState, rows: int) -> SwarmState:
    """Pad the particle axis to `rows` with inert copies of particle 0 (zero
    velocity, +inf fitness); `MPSO.step` keeps them inert."""
    extra = rows - state.positions.shape[0]
    if extra == 0:
        return state

    def pad(value, kind):
        if kind == "fitness":
            filler = jnp.full((extra,), jnp.inf, value.dtype)
        elif kind == "velocity":
            filler = jnp.zeros((extra,) + value.shape[1:], value.dtype)
        else:
            filler = jnp.broadcast_to(value[:1], (extra,) + value.shape[1:])
        return jnp.concatenate([value, filler])

    return eqx.tree_at(
        lambda s: (s.positions, s.velocities, s.fitness, s.pbest, s.pbest_fitness),
        state,
        (
            pad(state.positions, "position"),
            pad(state.velocities, "velocity"),
            pad(state.fitness, "fitness"),
            pad(state.pbest, "position"),
            pad(state.pbest_fitness, "fitness"),
        ),
    )


def _unpad_state(state: SwarmState, rows: int) -> SwarmState:
    if state.positions.shape[0] == rows:
        return state
    return _map_state(
        state, lambda a, particle: a[:rows] if particle else a, True, False
    )


def _replicate(tree, sharding):
    dynamic, static = eqx.partition(tree, eqx.is_array)
    return eqx.combine(jax.device_put(dynamic, sharding), static)


def run_swarm(
    objective: Callable[[Array, Any], ArrayLike],
    lower: Float[ArrayLike, " d"],
    upper: Float[ArrayLike, " d"],
    swarm: MPSO,
    key: PRNGKeyArray,
    *,
    args: Any = None,
    chunk_size: int = 100,
    progress: bool = False,
    target: float | None = None,
    stall_iterations: int | None = None,
    stall_tolerance: float = 0.0,
    sharding: Literal["auto"] | None = "auto",
    devices: Sequence[jax.Device] | None = None,
    throw: bool = True,
) -> SwarmResult:
    """Minimise `objective(x, args)` over the box `[lower, upper]` with `swarm`.

    **Arguments:**

    - `objective`: JAX-traceable `(x: (d,), args) -> scalar`. Non-finite values count
      as +inf, so diverging particles never become a best. Pass data through `args`
      rather than a fresh closure per call: the objective is a static argument of
      the jitted loop, so a new function object recompiles.
    - `lower`, `upper`: `(d,)` bounds of the search box.
    - `swarm`: the `MPSO` settings.
    - `key`: PRNG key; the same key gives the same result, whatever `chunk_size`,
      `sharding` or the number of devices.
    - `args`: passed to `objective` unchanged (a pytree; its arrays are traced).
    - `chunk_size`: iterations per jitted `lax.scan` (the first chunk starts with the
      initial evaluation, so it moves the swarm one time less). Between chunks the
      host checks for early stopping and prints progress; a smaller chunk reacts
      sooner, a larger one syncs less. The passes of the last chunk after a stop
      skip the objective.
    - `progress`: print a one-line progress bar to stderr after each chunk.
    - `target`: stop once the best fitness is `<= target`.
    - `stall_iterations`: stop once the best fitness has not improved by more than
      `stall_tolerance` for this many iterations.
    - `sharding`: `"auto"` splits the particles over `devices` (all visible devices
      when None) along a mesh axis `"particles"` whenever more than one device is in
      play, or when `devices` is given; `None` never shards. Sharded, each device
      gets the same number of rows, a multiple of 8 (whole CPU vectors: 250 rows a
      device ran 20 % slower than 256 on the AVX-512 CI machine); the rows beyond
      `num_particles` are inert dummy particles (never moving, fitness +inf), which
      cost their evaluations and do not change the result.
    - `devices`: the devices for `sharding="auto"`.
    - `throw`: as in optimistix: when True, raise a `RuntimeError` (naming the
      status and its fix) unless the run is successful, i.e. when an early-stopping
      rule was set but not met within `num_iterations`, or when no particle ever had
      a finite objective. When False, return the result anyway and report the
      status in `SwarmResult.result`. A fixed schedule (no `target`, no
      `stall_iterations`) only fails when the objective was never finite.

    **Returns:** a `SwarmResult`.
    """
    start = time.perf_counter()
    if not _is_int(chunk_size) or chunk_size < 1:
        raise ValueError(f"`chunk_size` must be an int >= 1, got {chunk_size!r}.")
    if stall_iterations is not None and (
        not _is_int(stall_iterations) or stall_iterations < 1
    ):
        raise ValueError(
            f"`stall_iterations` must be None or an int >= 1, got {stall_iterations!r}."
        )
    if sharding not in ("auto", None):
        raise ValueError(f'`sharding` must be "auto" or None, got {sharding!r}.')
    if sharding is None and devices is not None:
        raise ValueError('`devices` needs `sharding="auto"`.')
    if devices is not None and len(devices) == 0:
        raise ValueError("`devices` is empty.")
    n = swarm.num_particles
    length = min(chunk_size, swarm.num_iterations + 1)

    with _CompileTimer() as timer:
        particle_sharding = replicated_sharding = None
        rows = n
        if sharding == "auto" and (devices is not None or len(jax.devices()) > 1):
            device_list = list(jax.devices() if devices is None else devices)
            mesh = Mesh(np.asarray(device_list), ("particles",))
            particle_sharding = NamedSharding(mesh, PartitionSpec("particles"))
            replicated_sharding = NamedSharding(mesh, PartitionSpec())
            per_device = -(-n // len(device_list))
            rows = -(-per_device // _ROWS_MULTIPLE) * _ROWS_MULTIPLE * len(device_list)
            objective = _replicate(objective, replicated_sharding)
            args = _replicate(args, replicated_sharding)

        # The initial draw and evaluation (eq. 14) are the first iteration of the
        # first chunk, so the objective is compiled once, inside the loop.
        state = _unsampled(swarm, *_bounds(lower, upper))
        dtype = state.positions.dtype
        if particle_sharding is not None:
            state = _map_state(
                _pad_state(state, rows),
                jax.device_put,
                particle_sharding,
                replicated_sharding,
            )
        monitor = _Monitor(
            reference=state.gbest_fitness,
            last_improvement=jnp.asarray(np.zeros((), np.int32), jnp.int32),
        )
        target_array = np.asarray(-np.inf if target is None else target, dtype)
        stall_array = np.asarray(
            _NEVER if stall_iterations is None else stall_iterations, np.int32
        )
        tolerance_array = np.asarray(stall_tolerance, dtype)

        history = []
        iteration = -1
        code = _RUNNING
        while code == _RUNNING:
            state, monitor, chunk_history, code_array = _run_chunk(
                swarm,
                objective,
                state,
                monitor,
                key,
                args,
                target_array,
                stall_array,
                tolerance_array,
                length,
                particle_sharding,
                replicated_sharding,
            )
            new_iteration, code, chunk_history = jax.device_get(
                (state.iteration, code_array, chunk_history)
            )
            new_iteration, code = int(new_iteration), int(code)
            history.append(np.asarray(chunk_history[: new_iteration - iteration]))
            iteration = new_iteration
            if progress:
                _progress(
                    iteration,
                    swarm.num_iterations,
                    float(history[-1][-1]),
                    time.perf_counter() - start,
                )
        if progress:
            sys.stderr.write("\n")
            sys.stderr.flush()
        state = _unpad_state(state, n)

    history = np.concatenate(history)
    best_fitness = float(history[-1])
    early_stopping = target is not None or stall_iterations is not None
    result = SwarmResult(
        best_x=state.gbest,
        best_fitness=best_fitness,
        history=history,
        iterations_run=iteration,
        evaluations=n * (iteration + 1),
        wall_seconds=time.perf_counter() - start,
        compile_seconds=timer.seconds,
        stop_reason=_STOP_REASONS[code],
        result=_status(code, best_fitness, early_stopping),
        state=state,
    )
    if throw:
        raise_unless_successful(result.result, "run_swarm")
    return result
