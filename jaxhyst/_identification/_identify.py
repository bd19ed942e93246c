"""Identify a model from one recording or several: swarm (MPSO) -> gradient polish
-> `Fit`, with a status.

The stages are shared with the periodic steady-state fit (`_periodic.py`):
`search` runs the swarm over a problem's unit box, `refine` picks the best seed and
runs one polish after another, `Fit` carries the result and its `RESULTS` status.
The swarm searches with RK4 steps spanning several samples (every sample still
compared; rate-independent models barely notice the coarser integration); the polish
runs optimistix Levenberg-Marquardt (or BFGS, or optax Adam) on every sample from the
swarm's best; identifiability is read off the Jacobian at the result.
"""

import time
from collections.abc import Callable, Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, PRNGKeyArray

from .._memory_maps import release_if_near_map_limit
from .._metrics import error_metrics
from .._models.base import AbstractHysteresisModel, DataScales, signal_scales
from .._params import ParameterSpace
from .._placement import moved_to, running_on, serial_device
from .._recording import Recording
from .._simulate import RK4, AbstractSimulationSolver
from .._stability import stability_json
from .._status import RESULTS, raise_unless_successful, status_message, status_name
from .._swarm import MPSO, SwarmResult, run_swarm
from ._identifiability import (
    Identifiability,
    identifiability_of,
    output_jacobian,
)
from ._polish import AbstractPolish, LevenbergMarquardtPolish, PolishResult
from ._problem import (
    Problem,
    best_seed,
    model_at,
    stack_problems,
    swarm_objective,
    swarm_problem,
    swarm_samples_per_step,
)


class RecordingMetrics(eqx.Module):
    """The error metrics of a fit on one of the recordings it was fitted to."""

    recording: str
    metrics: dict[str, float]

    def to_dict(self) -> dict[str, Any]:
        return {"recording": self.recording, **self.metrics}


class Fit(eqx.Module):
    """The result of `identify` (or `fit_periodic`): the fitted model and everything
    that led to it.

    - `predicted`: the fitted model's output on the recording (a tuple of outputs,
      one per recording, when several were fitted together).
    - `metrics`: error metrics over every fitted sample; `per_recording`: the same
      for each recording, in the order given.
    - `result`: a `RESULTS` member, the last stage's status (the polish's, else the
      swarm's), `nonfinite` if the fitted model's output is not finite.
    """

    model: AbstractHysteresisModel
    predicted: Float[Array, " n"] | tuple[Float[Array, " n"], ...]
    metrics: dict[str, float]
    swarm: SwarmResult | None
    polish: PolishResult | None
    identifiability: Identifiability | None
    timing: dict[str, float]
    result: RESULTS = eqx.field(default_factory=lambda: RESULTS.successful)
    per_recording: tuple[RecordingMetrics, ...] = ()

    def for_recording(self, index: int) -> "Fit":
        """This fit seen on one of the recordings it was fitted to: `predicted` and
        `metrics` on that recording (the fit itself for a single recording)."""
        if not self.per_recording:
            if index != 0:
                raise IndexError(f"Fit.for_recording: one recording, got {index}.")
            return self
        predicted = self.predicted
        if not isinstance(predicted, tuple):
            raise TypeError("Fit.for_recording: per_recording without a tuple.")
        return eqx.tree_at(
            lambda f: (f.predicted, f.metrics, f.per_recording),
            self,
            (predicted[index], self.per_recording[index].metrics, ()),
        )

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready summary (the `jaxhyst fit --json` schema)."""
        metrics: dict[str, Any] = dict(self.metrics)
        if self.per_recording:
            metrics["per_recording"] = [m.to_dict() for m in self.per_recording]
        out: dict[str, Any] = {
            "model": type(self.model).__name__,
            "parameters": {k: float(v) for k, v in self.model.parameters().items()},
            "status": status_name(self.result),
            "status_message": status_message(self.result),
            "metrics": metrics,
            "timing": self.timing,
        }
        if self.swarm is not None:
            out["swarm"] = {
                "iterations": self.swarm.iterations_run,
                "evaluations": self.swarm.evaluations,
                "best_rmse": float(self.swarm.best_fitness),
                "stop_reason": self.swarm.stop_reason,
                "status": status_name(self.swarm.result),
            }
        if self.polish is not None:
            out["polish"] = {
                "method": self.polish.method,
                "steps": self.polish.steps,
                "converged": self.polish.converged,
                "status": status_name(self.polish.result),
                "rmse_history": [float(v) for v in self.polish.loss_history],
            }
        out["identifiability"] = (
            self.identifiability.to_dict() if self.identifiability is not None else {}
        )
        out["stability"] = stability_json(self.model)
        return out


# --------------------------------------------------------------------------- stages


def search(
    problem: Problem,
    swarm: MPSO,
    key: PRNGKeyArray,
    *,
    stall_iterations: int | None,
    chunk_size: int,
    progress: bool,
) -> SwarmResult:
    """The swarm over `problem`'s unit box; it stalls when its best RMSE has not
    improved by 1e-4 of the output scale for `stall_iterations` iterations."""
    d = problem.space.dimension
    return run_swarm(
        swarm_objective,
        jnp.asarray(np.zeros(d)),
        jnp.asarray(np.ones(d)),
        swarm,
        key,
        args=problem,
        progress=progress,
        chunk_size=chunk_size,
        stall_iterations=stall_iterations,
        stall_tolerance=1e-4 * float(problem.output_scale),
        throw=False,
    )


def starting_points(
    space: ParameterSpace,
    swarm_problem: Callable[[], Problem],
    swarm: MPSO | None,
    key: PRNGKeyArray,
    start: AbstractHysteresisModel | None,
    timing: dict[str, float],
    *,
    stall_iterations: int | None,
    chunk_size: int,
    progress: bool,
) -> tuple[list[Array], SwarmResult | None]:
    """The seeds of the polish: the swarm's best over `swarm_problem()` (unless
    `swarm` is None) and `start`'s coordinates (unless None, clipped to half a box
    beyond the bounds); the swarm's seconds go into `timing`."""
    seeds = []
    result = None
    if swarm is not None:
        result = search(
            swarm_problem(),
            swarm,
            key,
            stall_iterations=stall_iterations,
            chunk_size=chunk_size,
            progress=progress,
        )
        timing["swarm_s"] = result.wall_seconds
        seeds.append(result.best_x)
    if start is not None:
        seeds.append(jnp.clip(space.from_model(start), -0.5, 1.5))
    return seeds, result


class PolishStage(eqx.Module):
    """One polish of a pipeline: its name in `Fit.timing` (`<name>_s`), the problem
    it refines on, and the polish (None skips the stage)."""

    name: str
    problem: Problem
    polish: AbstractPolish | None


def refine(
    stages: Sequence[PolishStage], seeds: list[Array], timing: dict[str, float]
) -> tuple[Array, PolishResult | None]:
    """From the best of `seeds` (scored on the first stage's problem), run every
    stage's polish from the previous one's result; return the final point and the
    last polish's result, recording each stage's seconds in `timing`."""
    z = best_seed(stages[0].problem, seeds)
    last = None
    for stage in stages:
        if stage.polish is None:
            continue
        last = stage.polish.run(stage.problem, z)
        z = last.z
        timing[f"{stage.name}_s"] = last.wall_seconds
    return z, last


def fit_status(
    swarm: SwarmResult | None,
    polish: PolishResult | None,
    predicted: Sequence[Array],
) -> RESULTS:
    """The last stage's status, `nonfinite` where the fitted output is not."""
    if not all(bool(np.all(np.isfinite(np.asarray(p)))) for p in predicted):
        return RESULTS.nonfinite
    if polish is not None:
        return polish.result
    if swarm is not None:
        return swarm.result
    return RESULTS.successful


# ---------------------------------------------------------------------- identify


def _recordings(recording: Recording | Sequence[Recording]) -> list[Recording]:
    records = [recording] if isinstance(recording, Recording) else list(recording)
    if not records:
        raise ValueError("identify: no recordings given; pass one or a list of them.")
    for i, r in enumerate(records):
        if not isinstance(r, Recording):
            raise TypeError(
                f"identify: recording {i} is a {type(r).__name__}, not a Recording; "
                "use Recording(t, u, y) or Recording.load(path)."
            )
        r.require_samples(20, what="identification")
    inputs = {r.input_names[1:] for r in records}
    if len(inputs) > 1:
        raise ValueError(
            f"identify: the recordings carry different further inputs {sorted(inputs)};"
            " a joint fit needs the same inputs in every recording."
        )
    return records


def check_inputs(
    model: AbstractHysteresisModel, records: Sequence[Recording], owner: str
) -> None:
    """Raise unless every recording carries the inputs `model` reads."""
    needed = model.input_names
    for r in records:
        if r.num_inputs < len(needed):
            raise ValueError(
                f"{owner}: {type(model).__name__} reads {len(needed)} inputs "
                f"({', '.join(needed)}), recording {r.name!r} carries "
                f"{r.num_inputs} ({', '.join(r.input_names)}); load it with every "
                "input (Recording.load(path, input=[...]), or --input repeated on "
                "the command line: --input u --input v)."
            )


def joint_scales(recordings: Sequence[Recording]) -> DataScales:
    """The data scales of several recordings taken together (peaks, rms over all
    samples, the longest duration, the highest sample rate): what a joint fit's
    default bounds are set by. Recordings at different rates are bounded by the
    finest one: the fastest time scale any of them can show."""
    u = np.concatenate([np.asarray(r.u) for r in recordings])
    y = np.concatenate([np.asarray(r.y) for r in recordings])
    # Checked before squaring: a peak near overflow or underflow is refused with
    # its reason instead of an rms that overflowed (or underflowed) to inf (or 0).
    input_peak, input_rms = signal_scales(u, "input", "identify", constant=False)
    output_peak, output_rms = signal_scales(y, "output", "identify", constant=False)
    return DataScales(
        input_peak=input_peak,
        output_peak=output_peak,
        input_rms=input_rms,
        output_rms=output_rms,
        duration=max(r.duration for r in recordings),
        sample_rate=max(r.sample_rate for r in recordings),
        more_input_peaks=tuple(
            max(float(np.max(np.abs(r.more_inputs[i]))) for r in recordings)
            for i in range(recordings[0].num_inputs - 1)
        ),
    )


def _weights(weights, records: list[Recording]) -> list[Array | None]:
    if weights is None:
        return [None] * len(records)
    many = len(records) > 1
    given = list(weights) if many else [weights]
    if len(given) != len(records):
        raise ValueError(
            f"identify: {len(records)} recordings but {len(given)} weight arrays; "
            "pass one weight array per recording (or None)."
        )
    out = []
    for r, w in zip(records, given):
        w = None if w is None else jnp.asarray(w, float)
        if w is not None and w.shape != (r.num_samples,):
            raise ValueError(
                f"identify: weights for {r.name!r} must have one value per sample "
                f"({r.num_samples},), got {w.shape}."
            )
        out.append(w)
    return out


def identify(
    model: AbstractHysteresisModel,
    recording: Recording | Sequence[Recording],
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
    weights: Float[Array, " n"] | Sequence[Float[Array, " n"] | None] | None = None,
    gauge: bool = True,
    analyse: bool = True,
    progress: bool = False,
    polish_device: jax.Device | None = None,
    throw: bool = True,
) -> Fit:
    """Fit `model` (a template: its class, fixed parameters and smoothing) to
    `recording`, or to a list of recordings at once (one model for all of them:
    shared parameters, each recording simulated from its own initial state on its
    own time grid: recordings at different sample rates are fitted as they are,
    each RK4 step the interval of its own record, none resampled).

    - `space`: the free parameters and bounds; default `ParameterSpace.default`, set
      by the data's scales (all recordings together), which fixes the piezo gauge
      (A1) unless `gauge=False`.
    - `swarm`: MPSO settings (None skips the swarm and polishes from `start`).
      `MPSO.paper_case(3)` reproduces the paper's schedule (slow; the default finds
      the same basin in a fraction of the time).
    - `swarm_stride`: samples spanned by one RK4 step of the swarm's objective
      (default `swarm_samples_per_step(recording.u)`, the smallest over several
      recordings, one count of samples for all of them, so no record steps more of
      its input's path than its own choice; at different sample rates a step
      spans a longer time in the slower record): the loss landscape of a
      rate-independent model is set by the input's path, not the sample rate. Every sample is still compared (dense
      output, `RK4(samples_per_step=...)`); models that `RK4(samples_per_step=...)`
      cannot run are decimated instead. The polish integrates every sample.
    - `start`: a model to polish from (warm start) instead of, or in addition to, the
      swarm's best (the better of the two seeds the polish).
    - `stall_iterations`: stop the swarm when its best has not improved by 1e-4 of the
      output scale for this many iterations (None runs all iterations, as the paper).
    - `stable_only`: give +inf fitness to parameter sets outside Table 2.
    - `weights`: per-sample weights of the loss (a 0/1 mask fits part of the record
      while the model still runs through all of it); one array per recording when
      there are several. Metrics are over all samples.
    - `polish_device`: where the polish and everything after it run (one trajectory
      at a time: a sequential scan that a CPU runs faster than a GPU). None: the host
      CPU when the default device is an accelerator, else the default device.
    - `throw`: raise `RuntimeError` when `Fit.result` is not successful (the polish
      ran out of steps, or the fit is not finite); False returns the `Fit` with its
      status for you to inspect.
    """
    records = _recordings(recording)
    check_inputs(model, records, "identify")
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
    device = serial_device(polish_device, "polish_device")
    t_start = time.perf_counter()
    if space is None:
        space = ParameterSpace.default(model, joint_scales(records), gauge=gauge)
    per_record = [
        Problem(space, r.input_path(), jnp.asarray(r.y), solver, w, stable_only)
        for r, w in zip(records, _weights(weights, records))
    ]
    problem = per_record[0] if len(records) == 1 else stack_problems(per_record)
    release_if_near_map_limit("identify")
    # Every sample of every record (the fit's weights aside), padding masked.
    unweighted = [
        eqx.tree_at(lambda p: p.weights, p, None, is_leaf=lambda x: x is None)
        for p in per_record
    ]
    analysed = unweighted[0] if len(records) == 1 else stack_problems(unweighted)
    timing: dict[str, float] = {}
    stride = swarm_stride or min(swarm_samples_per_step(r.u) for r in records)
    seeds, swarm_result = starting_points(
        space,
        lambda: swarm_problem(problem, stride),
        swarm,
        key,
        start,
        timing,
        stall_iterations=stall_iterations,
        chunk_size=20,
        progress=progress,
    )
    problem, seeds, analysed = moved_to((problem, seeds, analysed), device)
    with running_on(device):
        z, polish_result = refine(
            [PolishStage("polish", problem, polish)], seeds, timing
        )
        fitted = model_at(problem.space, z)
        report = None
        if analyse:
            # One program gives the output and its sensitivities.
            t0 = time.perf_counter()
            jac, flat = output_jacobian(
                fitted, fitted.parameter_names, analysed.simulated
            )
            report = identifiability_of(
                fitted,
                jac,
                flat - np.asarray(analysed.measured).reshape(-1),
                weights=analysed.weights,
                free=space.names,
            )
            timing["identifiability_s"] = time.perf_counter() - t0
        else:
            flat = np.asarray(_simulated(analysed, fitted))
        simulated = flat.reshape(len(records), -1)
        predicted = tuple(
            jnp.asarray(simulated[i, : r.num_samples]) for i, r in enumerate(records)
        )
        metrics = error_metrics(
            np.concatenate([r.y for r in records]), np.concatenate(predicted)
        )
        per_recording = ()
        if len(records) > 1:
            per_recording = tuple(
                RecordingMetrics(r.name, error_metrics(r.y, p))
                for r, p in zip(records, predicted)
            )
    timing["total_s"] = time.perf_counter() - t_start
    fit = Fit(
        model=fitted,
        predicted=predicted[0] if len(records) == 1 else predicted,
        metrics=metrics,
        swarm=swarm_result,
        polish=polish_result,
        identifiability=report,
        timing=timing,
        result=fit_status(swarm_result, polish_result, predicted),
        per_recording=per_recording,
    )
    if throw:
        raise_unless_successful(fit.result, "identify")
    return fit


@eqx.filter_jit
def _simulated(problem: Problem, model: AbstractHysteresisModel):
    return problem.simulated(model)
