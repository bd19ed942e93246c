"""Integrate a model over a sampled input: a `lax.scan` classical RK4 (the workhorse,
fast under jit/vmap/grad) and a diffrax adaptive solver (the reference)."""

import abc
from typing import TYPE_CHECKING, Literal, overload

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._inputs import InputPath
from ._models.base import AbstractHysteresisModel


if TYPE_CHECKING:
    import diffrax


def _tsit5() -> "diffrax.AbstractSolver":
    import diffrax  # deferred: only the reference solver needs it (~0.15 s of import)

    return diffrax.Tsit5()


class AbstractSimulationSolver(eqx.Module):
    """How `simulate` integrates a model between samples."""

    @abc.abstractmethod
    def states(
        self,
        model: AbstractHysteresisModel,
        inputs: InputPath,
        initial_state: Float[Array, " s"],
    ) -> Float[Array, "n s"]:
        """The model state at every sample time, starting from `initial_state`."""


class RK4(AbstractSimulationSolver):
    """Classical fixed-step RK4 run as a `lax.scan` over sample intervals.

    Each sample interval is split into `substeps` equal RK4 steps; every step stays
    inside one interval, so with piecewise-linear input the integrand is smooth on each
    step and the method keeps its 4th order. Raise `substeps` for stiff or fast dynamics
    (inertia, high-frequency content) relative to the sample rate.

    `samples_per_step = k > 1` goes the other way: one RK4 step spans k sample
    intervals, and the state at the samples inside a step is the cubic Hermite
    interpolant of the step's end states and rates (dense output, 4th-order accurate
    like the step itself), so every sample is still simulated and compared. It costs
    about 1/k of the vector-field evaluations. Use it where the input varies slowly
    on the scale of k samples (a swarm's objective on a finely sampled record); it
    smears the rate kinks inside each step, so keep k = 1 for reference simulations.
    """

    substeps: int = eqx.field(default=1, static=True)
    samples_per_step: int = eqx.field(default=1, static=True, kw_only=True)

    def __check_init__(self):
        if not isinstance(self.substeps, int) or self.substeps < 1:
            raise ValueError(
                f"RK4(substeps={self.substeps!r}): substeps must be an integer >= 1."
            )
        k = self.samples_per_step
        if not isinstance(k, int) or isinstance(k, bool) or k < 1:
            raise ValueError(
                f"RK4(samples_per_step={k!r}): samples_per_step must be an integer "
                ">= 1."
            )
        if k > 1 and self.substeps > 1:
            raise ValueError(
                f"RK4(substeps={self.substeps}, samples_per_step={k}): choose one; "
                "substeps refines the step below the sample interval, samples_per_step "
                "coarsens it above."
            )

    def states(self, model, inputs, initial_state):
        if self.samples_per_step > 1:
            return self._coarse_states(model, inputs, initial_state)
        advance = self._advance(model, inputs)

        def over_interval(state, interval):
            state = advance(state, interval)
            return state, state

        intervals = jnp.arange(inputs.num_samples - 1)
        _, states = jax.lax.scan(over_interval, initial_state, intervals)
        return jnp.concatenate([initial_state[None], states])

    def _advance(self, model, inputs):
        """`advance(state, interval)`: the state at the end of sample interval
        `interval`, from the state at its start."""
        m = self.substeps
        dtype = inputs.values.dtype
        h = inputs.dt / m

        def rate(interval, frac, state):
            t = inputs.t0 + (interval + frac) * inputs.dt
            return _rate(model, inputs, t, interval, frac, state)

        def rk4_step(interval, j, state):
            f0 = jnp.asarray(j, dtype) / m
            f_half = (j + jnp.asarray(0.5, dtype)) / m
            f1 = (j + jnp.asarray(1.0, dtype)) / m
            k1 = rate(interval, f0, state)
            k2 = rate(interval, f_half, state + (h / 2) * k1)
            k3 = rate(interval, f_half, state + (h / 2) * k2)
            k4 = rate(interval, f1, state + h * k3)
            return state + (h / 6) * (k1 + 2 * k2 + 2 * k3 + k4)

        update = model.sample_update(inputs)

        def advance(state, interval):
            if m == 1:
                end = rk4_step(interval, 0, state)
            else:
                end = jax.lax.fori_loop(
                    0, m, lambda j, s: rk4_step(interval, j, s), state
                )
            return end if update is None else update(state, end, interval)

        return advance

    def _coarse(self, model, inputs, initial_state):
        """For `samples_per_step = k > 1`: `(steps, step, carry)` where `step(carry,
        i)` advances over sample intervals [i*k, (i+1)*k) and returns the new carry
        and the (k, s) states at samples i*k+1 .. (i+1)*k (by Hermite interpolation
        inside the step; samples past the record's end are extrapolated, mask them)."""
        if model.has_sample_update(inputs):
            raise ValueError(
                f"RK4(samples_per_step={self.samples_per_step}) cannot integrate "
                f"{type(model).__name__} in this configuration: part of it is "
                "propagated exactly once per sample (model.sample_update). Use "
                "samples_per_step=1."
            )
        k = self.samples_per_step
        n = inputs.num_samples
        dtype = inputs.values.dtype
        h = inputs.dt * k
        last_interval = n - 2

        def rate(position, state, from_left=False):
            # `position` counts sample intervals from t0; at a sample instant the rate
            # of the interval ahead is used, or of the one behind with `from_left`.
            if from_left:
                interval = jnp.ceil(position).astype(jnp.int32) - 1
            else:
                interval = jnp.floor(position).astype(jnp.int32)
            interval = jnp.clip(interval, 0, last_interval)
            frac = position - interval.astype(dtype)
            t = inputs.t0 + position * inputs.dt
            return _rate(model, inputs, t, interval, frac, state)

        theta = jnp.arange(1, k + 1, dtype=dtype) / k
        # Cubic Hermite basis at the samples inside a step (the last one is the node).
        h00 = 2 * theta**3 - 3 * theta**2 + 1
        h10 = theta**3 - 2 * theta**2 + theta
        h01 = -2 * theta**3 + 3 * theta**2
        h11 = theta**3 - theta**2

        def step(carry, i):
            state, slope = carry
            start = jnp.asarray(i * k, dtype)
            # With k even the midpoint is a sample instant, where the input's rate
            # may jump (a reversal): the two midpoint stages read it from either side.
            k2 = rate(start + k / 2, state + (h / 2) * slope, from_left=True)
            k3 = rate(start + k / 2, state + (h / 2) * k2)
            k4 = rate(start + k, state + h * k3, from_left=True)
            end = state + (h / 6) * (slope + 2 * k2 + 2 * k3 + k4)
            end_slope = rate(start + k, end)
            inside = (
                h00[:, None] * state[None]
                + (h * h10)[:, None] * slope[None]
                + h01[:, None] * end[None]
                + (h * h11)[:, None] * end_slope[None]
            )
            return (end, end_slope), inside

        steps = -(-(n - 1) // k)
        first_slope = rate(jnp.asarray(0, dtype), initial_state)
        return steps, step, (initial_state, first_slope)

    def _coarse_states(self, model, inputs, initial_state):
        steps, step, carry = self._coarse(model, inputs, initial_state)
        _, inside = jax.lax.scan(step, carry, jnp.arange(steps))
        inside = inside.reshape(-1, initial_state.shape[0])
        return jnp.concatenate([initial_state[None], inside])[: inputs.num_samples]


@eqx.filter_jit
def _rate(model, inputs, t, interval, frac, state):
    """The model's state rate at time `t` (inside sample interval `interval`, at
    fraction `frac` of it). One nested program: the four stages of an RK4 step (and
    their derivatives and batches) share one trace of the vector field instead of
    four; XLA inlines the call, so the compiled simulation is the same."""
    drive = model.drive(inputs, t, interval, frac)
    return model.vector_field(t, state, drive)


class DiffraxSolver(AbstractSimulationSolver):
    """An adaptive diffrax solve on the interpolated input: the reference against which
    the scan-RK4 is checked. Slower; use it to validate step sizes, not to fit.

    Sample instants are passed to the step-size controller as jump times, because the
    interpolated input (or its rate) has a kink there.
    """

    solver: "diffrax.AbstractSolver" = eqx.field(default_factory=_tsit5)
    rtol: float = 1e-8
    atol: float = 1e-10
    max_steps: int = eqx.field(default=1_000_000, static=True)

    def states(self, model, inputs, initial_state):
        import diffrax

        if model.has_sample_update(inputs):
            raise ValueError(
                f"DiffraxSolver cannot integrate {type(model).__name__} in this "
                "configuration: part of it is propagated exactly once per sample "
                "(model.sample_update), which only RK4 applies. Use RK4()."
            )

        def vector_field(t, state, path):
            return model.vector_field(t, state, model.drive(path, t))

        controller = diffrax.ClipStepSizeController(
            diffrax.PIDController(rtol=self.rtol, atol=self.atol),
            jump_ts=inputs.times,
        )
        solution = diffrax.diffeqsolve(
            diffrax.ODETerm(vector_field),
            self.solver,
            t0=inputs.t0,
            t1=inputs.t1,
            dt0=inputs.dt,
            y0=initial_state,
            args=inputs,
            saveat=diffrax.SaveAt(ts=inputs.times),
            stepsize_controller=controller,
            max_steps=self.max_steps,
        )
        ys = solution.ys
        if ys is None:  # pragma: no cover - SaveAt(ts=...) always saves
            raise RuntimeError("diffrax returned no states")
        return ys


def _sample_drive(model: AbstractHysteresisModel, inputs: InputPath, index):
    """The model's drive at sample `index` (right-continuous, the last sample read
    from the left)."""
    interval = jnp.minimum(index, inputs.num_samples - 2)
    frac = (index - interval).astype(inputs.dt.dtype)
    t = inputs.t0 + inputs.dt * jnp.asarray(index, inputs.dt.dtype)
    return model.drive(inputs, t, interval, frac)


def _sample_drives(model: AbstractHysteresisModel, inputs: InputPath):
    """The model's drive at every sample instant."""
    index = jnp.arange(inputs.num_samples)
    return jax.vmap(lambda i: _sample_drive(model, inputs, i))(index)


def _prepare(owner, model, inputs, solver, initial_state):
    """Check the arguments of `simulate`-like functions; returns the model cast to the
    input's dtype and the initial state."""
    if not isinstance(model, AbstractHysteresisModel):
        raise TypeError(
            f"{owner}: model must be a jaxhyst model (e.g. PiezoBoucWen), got "
            f"{type(model).__name__}."
        )
    if not isinstance(inputs, InputPath):
        raise TypeError(
            f"{owner}: inputs must be an InputPath, got {type(inputs).__name__}; "
            "build one with InputPath.from_samples(t, u), recording.input_path() or "
            "jaxhyst.sample(signal, rate)."
        )
    if not isinstance(solver, AbstractSimulationSolver):
        raise TypeError(
            f"{owner}: solver must be RK4(...) or DiffraxSolver(...), got "
            f"{type(solver).__name__}."
        )
    needed = len(model.input_names)
    if inputs.num_inputs < needed:
        raise ValueError(
            f"{owner}: {type(model).__name__} reads {needed} inputs "
            f"({', '.join(model.input_names)}), the input path carries "
            f"{inputs.num_inputs}; build it with InputPath(..., channels=...) or from a "
            "Recording with more inputs (Recording(..., more_inputs=...), --input "
            "repeated on the command line)."
        )
    dtype = inputs.values.dtype
    model = model.astype(dtype)
    if initial_state is None:
        initial_state = model.initial_state(_sample_drive(model, inputs, 0))
    initial_state = jnp.asarray(initial_state, dtype)
    if initial_state.shape != (model.state_size,):
        raise ValueError(
            f"{owner}: initial_state must have shape ({model.state_size},) for "
            f"{type(model).__name__}, got {initial_state.shape}."
        )
    return model, initial_state


@overload
def simulate(
    model: AbstractHysteresisModel,
    inputs: InputPath,
    solver: AbstractSimulationSolver = ...,
    *,
    initial_state: Float[Array, " s"] | None = ...,
    return_state: Literal[False] = ...,
    throw: bool = ...,
) -> Float[Array, " n"]: ...


@overload
def simulate(
    model: AbstractHysteresisModel,
    inputs: InputPath,
    solver: AbstractSimulationSolver = ...,
    *,
    initial_state: Float[Array, " s"] | None = ...,
    return_state: Literal[True],
    throw: bool = ...,
) -> tuple[Float[Array, " n"], Float[Array, "n s"]]: ...


@eqx.filter_jit
def simulate(
    model: AbstractHysteresisModel,
    inputs: InputPath,
    solver: AbstractSimulationSolver = RK4(),
    *,
    initial_state: Float[Array, " s"] | None = None,
    return_state: bool = False,
    throw: bool = True,
) -> Float[Array, " n"] | tuple[Float[Array, " n"], Float[Array, "n s"]]:
    """Simulate `model` driven by `inputs`; returns the output at every sample time
    (and the state, with `return_state=True`).

    One compiled program (`eqx.filter_jit`): the first call for a model type, solver
    and record length compiles it; new parameter values and inputs reuse it.

    The computation runs in the dtype of `inputs.values` (float32 or float64): the
    model's parameters are cast to it. With `throw=True` a non-finite result raises
    (under jit, through `eqx.error_if`); pass `throw=False` where divergence is
    expected and handled, e.g. inside a swarm's objective.
    """
    model, initial_state = _prepare("simulate", model, inputs, solver, initial_state)
    states = solver.states(model, inputs, initial_state)
    drives = _sample_drives(model, inputs)
    outputs = jax.vmap(model.output)(inputs.times, states, drives)
    if throw:
        outputs = eqx.error_if(
            outputs,
            ~jnp.all(jnp.isfinite(outputs)),
            "simulate: non-finite output (the model diverged). Check the parameters "
            "against bibo_stability(model), or use a finer grid (RK4(substeps=...)) "
            "or a smoothing rule (TanhSign(width)).",
        )
    if return_state:
        return outputs, states
    return outputs


@eqx.filter_jit
def sum_squared_error(
    model: AbstractHysteresisModel,
    inputs: InputPath,
    measured: Float[Array, " n"],
    solver: AbstractSimulationSolver = RK4(),
    *,
    weights: Float[Array, " n"] | None = None,
    initial_state: Float[Array, " s"] | None = None,
) -> Float[Array, ""]:
    """`sum((weights * (simulate(model, inputs) - measured))**2)`, NaN or inf if the
    model diverges.

    With `RK4` the error is accumulated inside the integration loop, so the trajectory
    is never stored: the form a swarm objective wants (less memory traffic per
    particle). Other solvers simulate first.
    """
    model, initial_state = _prepare(
        "sum_squared_error", model, inputs, solver, initial_state
    )
    n = inputs.num_samples
    measured = jnp.asarray(measured, inputs.values.dtype)
    if measured.shape != (n,):
        raise ValueError(
            f"sum_squared_error: measured must have shape ({n},) like the input, got "
            f"{measured.shape}."
        )
    weights = (
        jnp.ones_like(measured)
        if weights is None
        else jnp.asarray(weights, measured.dtype)
    )
    if not isinstance(solver, RK4):
        outputs = simulate(
            model, inputs, solver, initial_state=initial_state, throw=False
        )
        return jnp.sum((weights * (outputs - measured)) ** 2)

    def weighted_error(index, state):
        drive = _sample_drive(model, inputs, index)
        t = inputs.t0 + inputs.dt * jnp.asarray(index, inputs.dt.dtype)
        return weights[index] * (model.output(t, state, drive) - measured[index])

    first = weighted_error(0, initial_state)
    if solver.samples_per_step > 1:
        k = solver.samples_per_step
        steps, step, carry = solver._coarse(model, inputs, initial_state)
        offsets = jnp.arange(1, k + 1)

        def over_step(carry, i):
            (state, slope), total = carry
            (state, slope), inside = step((state, slope), i)
            index = i * k + offsets
            valid = index < n
            errors = jax.vmap(weighted_error)(jnp.minimum(index, n - 1), inside)
            # `where`, not a product: past the record's end the state may be inf.
            total = total + jnp.sum(jnp.where(valid, errors * errors, 0))
            return ((state, slope), total), None

        (_, total), _ = jax.lax.scan(
            over_step, (carry, first * first), jnp.arange(steps)
        )
        return total

    advance = solver._advance(model, inputs)

    def over_interval(carry, interval):
        state, total = carry
        state = advance(state, interval)
        error = weighted_error(interval + 1, state)
        return (state, total + error * error), None

    (_, total), _ = jax.lax.scan(
        over_interval, (initial_state, first * first), jnp.arange(n - 1)
    )
    return total
