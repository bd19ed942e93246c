"""Hysteresis compensation by causal per-sample inversion: the drive whose simulated
output follows a reference, one sample at a time, inside a `lax.scan`.

At every sample the model's state is known (it was driven by the drives found so
far); the next drive is the value in the amplifier's range, nearest the present
drive, whose one-interval simulation puts the output on the reference: a scalar
root, bracketed by intervals that double from the present drive on the side where
the output moves toward the reference, then bisected. Robust (no derivative
through the sign switch at a reversal), causal (it runs sample by sample as a
real-time feedforward would), and on the model's continuous branch: rate terms
fitted on a record's rates can fold the one-sample output over for jumps far
beyond them, where a root anywhere in the range would be a jump to another fold. A reference the model cannot reach inside the range gets
the drive that comes nearest (the limit's, for a monotone model), and those
samples are reported.

Models whose output lags the drive (stage dynamics, a drive shifted in time) have
no per-sample inverse: their output at a sample barely depends on that sample's
drive. Where the lag is the stage's second-order dynamics after the quasi-static
response (`PiezoStage`, `ExtendedPiezo` with dynamics), `DynamicInversion` computes
ahead of time the static response the stage needs, y + (2 zeta/omega) ydot +
yddot/omega^2 (the reference's derivatives are known in advance), and inverts the
quasi-static part for it sample by sample. Otherwise the whole drive is optimised
ahead of time through the differentiable simulator (`OptimisedDrive`): from the
per-sample inverse of the model's quasi-static part, fixed-point passes through the
full model (u <- u + (reference - y(u)) / slope) put the lagging share of the output
in time, then L-BFGS on the mean squared tracking error, the drive kept inside the
limits by a tanh map. A time shift delays only what the hysteresis sees (the paper's
y = k1*u(t) + k2*h[u(t + phi)]), so the drive is not shifted as a whole.
"""

import abc
import numbers
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
from jaxtyping import Array, ArrayLike, Bool, Float

from ._error_spectrum import ErrorSpectrum, error_spectrum
from ._inputs import InputPath
from ._models.base import AbstractHysteresisModel
from ._simulate import RK4, AbstractSimulationSolver, simulate
from ._status import RESULTS, raise_unless_successful
from ._uniform import uniform_series


class Compensation(eqx.Module):
    """The result of `compensate`.

    - `times`, `reference`: the reference y_ref(t) as given.
    - `drive`: u(t), inside `limits`.
    - `predicted`: the model's output under `drive` (what the stage would do if it
      were the model).
    - `at_limit`: samples whose reference the model cannot reach inside `limits`
      (their drive is the nearer limit, or for a model that folds, the drive that
      came nearest the reference).
    - `result`: `successful`, or `nonfinite` when the model diverged.
    - `method`: "per-sample inversion", "dynamic inversion" or "optimised drive".
    - `slew_limit`: the amplifier's largest drive rate |du/dt| given to
      `compensate` (drive units per second), or None.
    - `over_slew`: samples the drive reaches from the previous one faster than
      `slew_limit` (None without one): the amplifier cannot follow the drive
      there, so the stage will lag the prediction. Reported, never smoothed away.
    """

    times: Float[Array, " n"]
    reference: Float[Array, " n"]
    drive: Float[Array, " n"]
    predicted: Float[Array, " n"]
    at_limit: Bool[Array, " n"]
    limits: tuple[float, float]
    result: RESULTS
    method: str = "per-sample inversion"
    slew_limit: float | None = None

    @property
    def error(self) -> Float[Array, " n"]:
        """Predicted minus reference output."""
        return self.predicted - self.reference

    def _rates(self) -> np.ndarray:
        """|du/dt| over each interval between samples (drive units per second)."""
        dt = float(np.mean(np.diff(np.asarray(self.times, dtype=float))))
        return np.abs(np.diff(np.asarray(self.drive))) / dt

    @property
    def over_slew(self) -> Bool[Array, " n"] | None:
        """Samples the drive reaches from the previous one faster than `slew_limit`
        (None without one); a rounding-level excess is not one."""
        if self.slew_limit is None:
            return None
        fast = self._rates() > self.slew_limit * (1 + 1e-9)
        return jnp.asarray(np.concatenate([[False], fast]))

    def tracking(self) -> dict[str, float]:
        """RMS and maximum predicted tracking error in output units and in % of the
        reference's stroke (its peak-to-peak range), how many samples are at a
        limit, how many the drive reaches faster than `slew_limit`, and the drive's
        largest rate |du/dt| (drive units per second)."""
        error = np.asarray(self.error)
        stroke = float(np.ptp(np.asarray(self.reference)))
        rms = float(np.sqrt(np.mean(error**2)))
        peak = float(np.max(np.abs(error)))
        scale = 100.0 / stroke if stroke > 0 else float("nan")
        return {
            "rms_error": rms,
            "max_error": peak,
            "rms_error_percent_of_stroke": rms * scale,
            "max_error_percent_of_stroke": peak * scale,
            "samples_at_limit": int(np.count_nonzero(np.asarray(self.at_limit))),
            "samples_over_slew": (
                0
                if self.over_slew is None
                else int(np.count_nonzero(np.asarray(self.over_slew)))
            ),
            "max_slew_rate": float(np.max(self._rates())),
        }

    def error_spectrum(self) -> ErrorSpectrum:
        """Where the predicted tracking error lies in frequency: its RMS in octave
        bands, with percentages of the reference's stroke (see `jh.error_spectrum`;
        apply that to a measured error to see where the stage itself misses)."""
        return error_spectrum(
            self.times, self.error, stroke=float(np.ptp(np.asarray(self.reference)))
        )


def _one_interval(model, solver, t, dt, state, u_now, u_next):
    """Output and state one sample after `state` when the drive ramps from `u_now`
    to `u_next`."""
    path = InputPath(t, dt, jnp.stack([u_now, u_next]))
    outputs, states = simulate(
        model, path, solver, initial_state=state, return_state=True, throw=False
    )
    return outputs[1], states[1]


def _bisect(function, target, lo, hi, iterations):
    """The drive in [lo, hi] where the monotone `function` meets `target`, or the
    nearer end when it does not (then `at_limit`)."""
    f_lo, f_hi = function(lo), function(hi)
    rising = f_hi >= f_lo
    # Beyond an end by more than rounding (the reference may come from the end).
    slack = 1e-9 * jnp.abs(f_hi - f_lo)
    below = jnp.where(rising, target < f_lo - slack, target > f_lo + slack)
    above = jnp.where(rising, target > f_hi + slack, target < f_hi - slack)

    def halve(_, bracket):
        a, b = bracket
        mid = 0.5 * (a + b)
        low_side = jnp.where(rising, function(mid) < target, function(mid) > target)
        return jnp.where(low_side, mid, a), jnp.where(low_side, b, mid)

    a, b = jax.lax.fori_loop(0, iterations, halve, (lo, hi))
    u = jnp.where(below, lo, jnp.where(above, hi, 0.5 * (a + b)))
    return u, below | above


# The first bracket is the drive range / 2**_EXPANSIONS wide; it doubles until the
# reference is crossed or the limit is reached.
_EXPANSIONS = 16


def _branch_crossing(function, target, u_now, lo, hi, iterations):
    """(u, out_of_reach): the drive nearest `u_now` where `function` crosses
    `target`, searched on the side of `u_now` where the output moves toward the
    target (the output's slope at `u_now` from its values a first bracket away on
    either side).

    Brackets (hi - lo) * 2**(k - 16) wide grow from `u_now` towards that limit
    until one holds a crossing, which is bisected until it is one float wide or
    after `iterations` halvings. A model whose one-sample output is not monotone in
    the drive (rate terms fitted on a record's rates can fold it over for jumps far
    beyond them) thus keeps to its continuous branch instead of jumping to a
    distant root on a fold. Without a crossing before the limit, the drive is the
    one tried whose output came nearest the target (the limit, for a monotone
    model) and the sample is out of reach."""
    f_now = function(u_now)
    g0 = f_now - target
    first = jnp.ldexp(hi - lo, -_EXPANSIONS)
    up, down = jnp.minimum(u_now + first, hi), jnp.maximum(u_now - first, lo)
    rising = function(up) >= function(down)  # the output's slope at u_now
    direction = jnp.where(rising == (g0 < 0), 1.0, -1.0)
    end = jnp.where(direction > 0, hi, lo)

    def not_crossed(g):
        return g * g0 > 0

    def expanding(carry):
        k, found, _, last = carry[:4]
        return ~found & (k <= _EXPANSIONS) & (last != end)

    def expand(carry):
        k, _, a, b, best, g_best = carry
        trial = u_now + direction * jnp.ldexp(hi - lo, k - _EXPANSIONS)
        trial = jnp.where(direction > 0, jnp.minimum(trial, hi), jnp.maximum(trial, lo))
        g = function(trial) - target
        found = ~not_crossed(g)
        closer = jnp.abs(g) < jnp.abs(g_best)
        best, g_best = jnp.where(closer, trial, best), jnp.where(closer, g, g_best)
        return k + 1, found, b, trial, best, g_best

    start = (0, g0 == 0, u_now, u_now, u_now, g0)
    _, found, a, b, best, g_best = jax.lax.while_loop(expanding, expand, start)

    def halving(carry):
        i, a, b = carry
        mid = 0.5 * (a + b)
        return (i < iterations) & (mid != a) & (mid != b)

    def halve(carry):
        i, a, b = carry
        mid = 0.5 * (a + b)
        keep_b = not_crossed(function(mid) - target)
        return i + 1, jnp.where(keep_b, mid, a), jnp.where(keep_b, b, mid)

    _, a, b = jax.lax.while_loop(halving, halve, (0, a, b))
    # Within rounding of the target counts as met (it may come from the limit).
    slack = 1e-9 * jnp.maximum(jnp.abs(target), jnp.abs(f_now))
    out_of_reach = ~found & (jnp.abs(g_best) > slack)
    return jnp.where(found, 0.5 * (a + b), best), out_of_reach


@eqx.filter_jit
def _invert(model, solver, t0, dt, reference, lo, hi, iterations):
    def output_at_rest(u):
        path = InputPath(t0, dt, jnp.stack([u, u]))
        return simulate(model, path, solver, throw=False)[0]

    u0, limited0 = _bisect(output_at_rest, reference[0], lo, hi, iterations)
    rest = InputPath(t0, dt, jnp.stack([u0, u0]))
    state0 = simulate(model, rest, solver, return_state=True, throw=False)[1][0]

    def step(carry, inputs):
        state, u_now = carry
        k, target = inputs
        t = t0 + k * dt

        def output(u):
            return _one_interval(model, solver, t, dt, state, u_now, u)[0]

        u, limited = _branch_crossing(output, target, u_now, lo, hi, iterations)
        y, new_state = _one_interval(model, solver, t, dt, state, u_now, u)
        return (new_state, u), (u, y, limited)

    index = jnp.arange(reference.size - 1, dtype=reference.dtype)
    _, (drive, predicted, limited) = jax.lax.scan(
        step, (state0, u0), (index, reference[1:])
    )
    y0 = simulate(model, rest, solver, throw=False)[0]
    return (
        jnp.concatenate([u0[None], drive]),
        jnp.concatenate([y0[None], predicted]),
        jnp.concatenate([limited0[None], limited]),
    )


def _static_inverse(
    model, solver, times: np.ndarray, target: Array, lo: float, hi: float, start
) -> tuple[Array, Array]:
    """(drive, at_limit): `start`'s inverse of the model's quasi-static part for
    `target`. Not shifted by the model's time shift: the shift delays only what
    the hysteresis sees (y = k1*u(t) + k2*h[u(t + phi)]), so shifting the whole drive
    would mistime the linear term, which dominates the output; `OptimisedDrive`'s
    refinement passes put the hysteresis's share in time."""
    u0, _, at_limit = start.drive(model.quasi_static(), solver, times, target, lo, hi)
    return jnp.asarray(u0, target.dtype), at_limit


def _stage_inverse(
    model, stage, solver, times: np.ndarray, reference: Array, lo, hi, start
) -> tuple[Array, Array]:
    """(drive, at_limit): the static response the stage `stage`
    (`model.stage_dynamics()`: omega, zeta, drift) needs for `reference`, y_s = y + (2 zeta/omega) ydot + yddot/omega^2
    (the reference less the drift, by central differences), inverted by
    `_static_inverse`."""
    omega, zeta, drift = stage
    dt = float(np.mean(np.diff(times)))
    settled = np.asarray(reference) - drift(times)
    rate = np.gradient(settled, dt, edge_order=2)
    acceleration = np.gradient(rate, dt, edge_order=2)
    target = reference + jnp.asarray(
        (2 * zeta / omega) * rate + acceleration / omega**2, reference.dtype
    )
    return _static_inverse(model, solver, times, target, lo, hi, start)


def _grid(times: np.ndarray, reference: Array, lo: float, hi: float):
    """(t0, dt, lo, hi) as arrays of the reference's dtype (traced, so new values
    do not recompile)."""
    dtype = reference.dtype
    dt = float(np.mean(np.diff(times)))
    return tuple(jnp.asarray(v, dtype) for v in (times[0], dt, lo, hi))


class AbstractCompensationMethod(eqx.Module):
    """How `compensate` finds the drive."""

    name: eqx.AbstractClassVar[str]

    @abc.abstractmethod
    def drive(
        self, model, solver, times: np.ndarray, reference: Array, lo: float, hi: float
    ) -> tuple[Array, Array, Array]:
        """(drive, predicted output, at_limit) for the reference."""


class PerSampleInversion(AbstractCompensationMethod):
    """Causal: at every sample, the drive nearest the present one whose one-sample
    simulation meets the reference: brackets from 2**-16 of the drive range, doubling
    from the present drive toward the reference, then at most `iterations` bisection
    halvings (they stop at float64 resolution, which 52 always reach). For models
    without a lag (see the module docstring)."""

    iterations: int = 52
    name: ClassVar[str] = "per-sample inversion"

    def __check_init__(self):
        k = self.iterations
        if not isinstance(k, int) or isinstance(k, bool) or k < 1:
            raise ValueError(
                f"PerSampleInversion(iterations={k!r}): must be an integer >= 1."
            )

    def drive(self, model, solver, times, reference, lo, hi):
        why = model.lag_reason()
        if why is not None:
            raise ValueError(
                f"compensate: {why}, so the drive cannot be found sample by sample; "
                "use method=DynamicInversion() (stage dynamics) or OptimisedDrive() "
                "(the defaults for such models)."
            )
        t0, dt, low, high = _grid(times, reference, lo, hi)
        return _invert(model, solver, t0, dt, reference, low, high, self.iterations)


class DynamicInversion(AbstractCompensationMethod):
    """Ahead of time, for models whose lag is a second-order stage after the
    quasi-static response (`PiezoStage`, `ExtendedPiezo` with dynamics): the static
    response the stage needs, y_s = y + (2 zeta/omega) ydot + yddot/omega^2 (the
    reference less the model's drift, differentiated by central differences), then
    `start`'s per-sample inverse of the quasi-static part for it. Exact as the
    sample interval shrinks against the resonance period (the differences are
    second-order accurate); a reference with steps asks for a very large static
    response at each step, where the drive meets its limits (flagged)."""

    start: PerSampleInversion = PerSampleInversion()
    name: ClassVar[str] = "dynamic inversion"

    def drive(self, model, solver, times, reference, lo, hi):
        stage = model.stage_dynamics()
        if stage is None:
            raise ValueError(
                f"compensate: {type(model).__name__} has no stage dynamics for "
                "DynamicInversion to invert; use method=PerSampleInversion() (models "
                "without a lag) or OptimisedDrive() (a time shift)."
            )
        if model.time_shift():
            raise ValueError(
                f"compensate: this {type(model).__name__} also reads the drive "
                f"shifted in time (phi = {model.time_shift():g} s), which "
                "DynamicInversion does not invert; use method=OptimisedDrive() (the "
                "default for such models)."
            )
        drive, at_limit = _stage_inverse(
            model, stage, solver, times, reference, lo, hi, self.start
        )
        t0, step, _, _ = _grid(times, reference, lo, hi)
        predicted = simulate(model, InputPath(t0, step, drive), solver, throw=False)
        return drive, predicted, at_limit


class OptimisedDrive(AbstractCompensationMethod):
    """Ahead of time: the whole drive minimising the mean squared tracking error
    through the differentiable simulator. Starts from `DynamicInversion`'s drive
    for a model with stage dynamics, else from the per-sample inverse of the
    model's quasi-static part; then `passes` fixed-point passes through the full
    model, u <- u + (reference - y(u)) / s (s: the least-squares slope of the
    model's output on the drive; the best pass is kept), which put the lagging
    share of the output in time; then `steps` L-BFGS steps on the mean squared
    error, the drive kept strictly inside the limits (u = mid + half*tanh(v)).
    The steps stop early once the RMS error is below `rtol` times the reference's
    largest magnitude. Raise `steps` when the tracking error is still falling;
    `passes=0` skips the fixed-point passes. The cost grows with (passes + steps)
    x samples: a minute for 10 000 samples on a laptop core."""

    steps: int = 300
    passes: int = 30
    rtol: float = 1e-7
    start: PerSampleInversion = PerSampleInversion()
    name: ClassVar[str] = "optimised drive"

    def __check_init__(self):
        for name, low in (("steps", 1), ("passes", 0)):
            k = getattr(self, name)
            if not isinstance(k, int) or isinstance(k, bool) or k < low:
                raise ValueError(
                    f"OptimisedDrive({name}={k!r}): must be an integer >= {low}."
                )
        if not (isinstance(self.rtol, int | float) and 0 <= self.rtol < 1):
            raise ValueError(
                f"OptimisedDrive(rtol={self.rtol!r}): must be a number in [0, 1)."
            )

    def drive(self, model, solver, times, reference, lo, hi):
        stage = model.stage_dynamics()
        if stage is not None:
            start, _ = _stage_inverse(
                model, stage, solver, times, reference, lo, hi, self.start
            )
        else:
            start, _ = _static_inverse(
                model, solver, times, reference, lo, hi, self.start
            )
        t0, dt, low, high = _grid(times, reference, lo, hi)
        refined = _refine(
            model, solver, t0, dt, reference, start, low, high, self.passes
        )
        rtol = jnp.asarray(self.rtol, reference.dtype)
        drive, predicted = _optimise(
            model, solver, t0, dt, reference, refined, low, high, self.steps, rtol
        )
        margin = 1e-6 * (hi - lo)
        at_limit = (drive <= lo + margin) | (drive >= hi - margin)
        return drive, predicted, at_limit


@eqx.filter_jit
def _refine(model, solver, t0, dt, reference, u0, lo, hi, passes):
    """`passes` fixed-point passes u <- clip(u + (reference - y(u)) / s) from `u0`,
    s the least-squares slope of the model's output on the drive along `u0`; the
    pass with the least mean squared error (u0 included) is returned. They
    converge while the output's response to the present drive dominates the
    lagging part's (a time-shifted hysteresis, slow creep)."""
    y0 = simulate(model, InputPath(t0, dt, u0), solver, throw=False)
    du, dy = u0 - jnp.mean(u0), y0 - jnp.mean(y0)
    slope = jnp.sum(du * dy) / jnp.maximum(jnp.sum(du**2), 1e-300)
    usable = jnp.isfinite(slope) & (jnp.abs(slope) > 0)
    slope = jnp.where(usable, slope, 1.0)

    def one_pass(carry, _):
        u, best, best_loss = carry
        y = simulate(model, InputPath(t0, dt, u), solver, throw=False)
        loss = jnp.mean((y - reference) ** 2)
        better = jnp.isfinite(loss) & (loss < best_loss)
        best = jnp.where(better, u, best)
        best_loss = jnp.where(better, loss, best_loss)
        step = jnp.where(usable & jnp.isfinite(y), (reference - y) / slope, 0.0)
        return (jnp.clip(u + step, lo, hi), best, best_loss), None

    start = (u0, u0, jnp.asarray(jnp.inf, reference.dtype))
    (u, best, best_loss), _ = jax.lax.scan(one_pass, start, None, length=passes)
    y = simulate(model, InputPath(t0, dt, u), solver, throw=False)
    last_loss = jnp.mean((y - reference) ** 2)
    return jnp.where(jnp.isfinite(last_loss) & (last_loss < best_loss), u, best)


@eqx.filter_jit
def _optimise(model, solver, t0, dt, reference, u0, lo, hi, steps, rtol):
    mid, half = (hi + lo) / 2, (hi - lo) / 2
    inside = jnp.clip((u0 - mid) / half, -1 + 1e-9, 1 - 1e-9)
    scale = jnp.maximum(jnp.max(jnp.abs(reference)), 1e-300)

    def drive_of(v):
        return mid + half * jnp.tanh(v)

    def loss(v):
        y = simulate(model, InputPath(t0, dt, drive_of(v)), solver, throw=False)
        return jnp.mean(((y - reference) / scale) ** 2)

    optimiser = optax.lbfgs()
    value_and_grad = optax.value_and_grad_from_state(loss)

    def step(carry):
        k, v, state, _ = carry
        value, grad = value_and_grad(v, state=state)
        updates, state = optimiser.update(
            grad, state, v, value=value, grad=grad, value_fn=loss
        )
        return k + 1, optax.apply_updates(v, updates), state, value

    def going(carry):
        k, _, _, value = carry  # the loss before the last step
        return (k < steps) & ~(value <= rtol**2)

    v0 = jnp.arctanh(inside)
    infinite = jnp.asarray(jnp.inf, reference.dtype)
    _, v, _, _ = jax.lax.while_loop(going, step, (0, v0, optimiser.init(v0), infinite))
    drive = drive_of(v)
    predicted = simulate(model, InputPath(t0, dt, drive), solver, throw=False)
    return drive, predicted


def compensate(
    model: AbstractHysteresisModel,
    times: Float[ArrayLike, " n"],
    reference: Float[ArrayLike, " n"],
    *,
    limits: tuple[float, float],
    slew_limit: float | None = None,
    method: AbstractCompensationMethod | None = None,
    solver: AbstractSimulationSolver = RK4(),
    throw: bool = True,
) -> Compensation:
    """The drive u(t) within `limits` (the amplifier's range, e.g. (0.0, 150.0) V)
    whose simulated output follows `reference` at the uniformly spaced `times`.

    `method`: `PerSampleInversion()` (causal, exact for the model; the default for
    models without a lag), `DynamicInversion()` (the stage's dynamics inverted on
    the reference ahead of time, then the per-sample inverse; the default for models
    with stage dynamics and no time shift) or `OptimisedDrive()` (the whole drive
    optimised ahead of time; the default for a time shift, and the most exact for
    any lagging model where its minute is affordable). `Compensation.method` says
    which ran. Samples the model cannot reach inside `limits` are flagged in
    `at_limit`, never silently clipped; with `slew_limit` (the amplifier's largest
    |du/dt|, drive units per second), the samples the drive reaches faster than that
    are flagged in `over_slew` (the drive is not smoothed: where the amplifier
    cannot follow it, the stage lags the prediction). The model starts at rest at the first sample's drive; pass the `solver` the model
    was fitted with (e.g. `RK4(substeps=4)` for `PiezoStage`). `throw=True` raises
    when the model diverged.
    """
    if not isinstance(model, AbstractHysteresisModel):
        raise TypeError(
            f"compensate: model must be a jaxhyst model, got {type(model).__name__}."
        )
    if method is None:
        if model.stage_dynamics() is not None and not model.time_shift():
            method = DynamicInversion()
        elif model.lag_reason() is not None:
            method = OptimisedDrive()
        else:
            method = PerSampleInversion()
    if not isinstance(method, AbstractCompensationMethod):
        raise TypeError(
            "compensate: method must be PerSampleInversion(), DynamicInversion() or "
            f"OptimisedDrive(), got {type(method).__name__}."
        )
    t, r, _ = uniform_series(
        "compensate", times, reference, name="reference", minimum=2
    )
    lo, hi = (float(v) for v in limits)
    if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
        raise ValueError(
            f"compensate: limits must be finite with lower < upper, got {limits}."
        )
    if slew_limit is not None:
        if isinstance(slew_limit, bool) or not isinstance(slew_limit, numbers.Real):
            raise TypeError(
                "compensate: slew_limit must be a number (drive units per second) "
                f"or None, got {type(slew_limit).__name__}."
            )
        if not (np.isfinite(slew_limit) and slew_limit > 0):
            raise ValueError(
                "compensate: slew_limit must be positive and finite (drive units "
                f"per second, e.g. 1e4 for 10 V/ms), got {slew_limit!r}."
            )
        slew_limit = float(slew_limit)
    r_array = jnp.asarray(r)
    drive, predicted, at_limit = method.drive(model, solver, t, r_array, lo, hi)
    finite = bool(np.all(np.isfinite(np.asarray(predicted))))
    result = RESULTS.successful if finite else RESULTS.nonfinite
    out = Compensation(
        jnp.asarray(t, r_array.dtype),
        r_array,
        drive,
        predicted,
        at_limit,
        (lo, hi),
        result,
        method.name,
        slew_limit,
    )
    if throw:
        raise_unless_successful(result, "compensate")
    return out
