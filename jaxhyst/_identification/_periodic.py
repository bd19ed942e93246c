"""Identification from periodic records (multisines), as in the Bouc-Wen benchmark.

A periodic excitation repeated P times gives, once its start-up transient has died
out, P noisy copies of one steady-state period. For a model in steady state the
least-squares fit to all P copies and the fit to their average have the same
minimiser, so `average_periods` folds the record and the fit simulates one period
(plus a short warm-up) instead of P; the spread between the periods measures the
noise.

`PeriodicSimulation` runs a model to periodic steady state: from rest through a
warm-up (the tail of the period) and then one period, which is scored. Between
samples the input is rebuilt by trigonometric (FFT) interpolation, which is exact
for a periodic input band-limited below the Nyquist frequency, and cubic Hermite
interpolation on that finer grid. At 750 Hz a 150 Hz multisine is sampled five
times per period of its fastest line: piecewise-linear input costs 7e-6 m of test
error on the benchmark, cubic 6e-7 m and band-limited upsampling 2.5e-7 m.

`fit_periodic` is `identify` for such records: a swarm on a cheap, shortened copy,
Levenberg-Marquardt on the whole period at the same cheap resolution, then on the
whole period with the accurate simulation, then identifiability from the Jacobian
at the result (`periodic_identifiability`). `oscillator_space` gives the
benchmark oscillator a log-scaled search box set by the data's scales.
"""

import math
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, PRNGKeyArray

from .._inputs import AbstractInterpolation, CubicInterpolation, InputPath
from .._metrics import error_metrics
from .._models.base import AbstractHysteresisModel, DataScales
from .._models.oscillator import HystereticOscillator
from .._params import ParameterSpace
from .._placement import moved_to, running_on, serial_device
from .._recording import Recording
from .._simulate import RK4, AbstractSimulationSolver, simulate
from .._status import raise_unless_successful
from .._swarm import MPSO
from ._identifiability import Identifiability, identifiability
from ._identify import Fit, PolishStage, fit_status, refine, starting_points
from ._polish import AbstractPolish, LevenbergMarquardtPolish
from ._problem import Problem


def bandlimited_upsample(
    period: Float[ArrayLike, " n"], factor: int
) -> Float[np.ndarray, " m"]:
    """`factor` times as many samples of one period of a periodic signal, by
    trigonometric (FFT zero-padding) interpolation: exact for a signal with no
    content at or above the Nyquist frequency. The original samples are kept."""
    values = np.asarray(period, dtype=float)
    if values.ndim != 1 or values.size < 2:
        raise ValueError(
            f"bandlimited_upsample: need one period as a 1-D array of at least 2 "
            f"samples, got shape {values.shape}."
        )
    if not isinstance(factor, int) or factor < 1:
        raise ValueError(
            f"bandlimited_upsample: factor must be an integer >= 1, got {factor!r}."
        )
    if factor == 1:
        return values.copy()
    n = values.size
    spectrum = np.fft.rfft(values)
    padded = np.zeros(n * factor // 2 + 1, dtype=complex)
    padded[: spectrum.size] = spectrum
    if n % 2 == 0:  # the Nyquist line is shared by +/- frequencies: split it
        padded[n // 2] *= 0.5
    return np.fft.irfft(padded, n * factor) * factor


class PeriodicAverage(eqx.Module):
    """One steady-state period, averaged over the periods of a record.

    - `recording`: the averaged period (time from 0).
    - `periods`: how many periods were averaged.
    - `noise_sigma`: per-sample noise of one period, from the spread between periods
      (unbiased); the average carries `noise_sigma / sqrt(periods)`.
    - `skipped`: leading periods left out (start-up transient).
    """

    recording: Recording
    periods: int
    noise_sigma: float
    skipped: int

    @property
    def mean_sigma(self) -> float:
        """Noise standard deviation of the averaged period."""
        return self.noise_sigma / math.sqrt(self.periods)


def average_periods(
    recording: Recording, period: int, *, skip: int = 1
) -> PeriodicAverage:
    """Fold `recording` into periods of `period` samples, drop the first `skip` (the
    transient from rest) and average the rest. The input must repeat exactly."""
    n = recording.num_samples
    if not isinstance(period, int) or period < 2 or n % period:
        raise ValueError(
            f"average_periods: {n} samples are not a whole number of periods of "
            f"{period!r} samples; pass the period length in samples."
        )
    total = n // period
    if not isinstance(skip, int) or not 0 <= skip <= total - 2:
        raise ValueError(
            f"average_periods: skip={skip!r} must leave at least 2 of the {total} "
            "periods (the noise is read from their spread)."
        )
    u = recording.u.reshape(total, period)[skip:]
    y = recording.y.reshape(total, period)[skip:]
    spread = float(np.max(np.abs(u - u[0])))
    if spread > 1e-9 * float(np.max(np.abs(u))):
        raise ValueError(
            f"average_periods: the input is not periodic with {period} samples (its "
            f"periods differ by up to {spread:.3g}); averaging needs an exactly "
            "repeated excitation."
        )
    mean = y.mean(axis=0)
    kept = y.shape[0]
    noise_sigma = float(np.sqrt(np.sum((y - mean) ** 2) / (period * (kept - 1))))
    averaged = Recording(
        np.arange(period) * recording.dt,
        u[0],
        mean,
        name=f"{recording.name}_period_average",
        input_name=recording.input_name,
        output_name=recording.output_name,
        input_unit=recording.input_unit,
        output_unit=recording.output_unit,
        time_unit=recording.time_unit,
    )
    return PeriodicAverage(averaged, kept, noise_sigma, skip)


class PeriodicSimulation(eqx.Module):
    """How a model is run to periodic steady state over one period of an input.

    The model starts at rest `warmup` seconds before the period (the input there is
    the period's tail, i.e. the periodic input continued backwards) and is scored on
    the period that follows. The input is upsampled `upsample` times by FFT
    interpolation, then read with `interpolation`; `solver` integrates on the fine
    grid (so RK4(substeps=k) takes upsample*k steps per original sample).
    Make `warmup` several decay times of the slowest mode; check it by comparing
    with a longer one.
    """

    warmup: float = 2.0
    upsample: int = eqx.field(default=4, static=True)
    solver: AbstractSimulationSolver = RK4(substeps=2)
    interpolation: AbstractInterpolation = CubicInterpolation()

    def __check_init__(self):
        if not isinstance(self.upsample, int) or self.upsample < 1:
            raise ValueError(
                f"PeriodicSimulation: upsample must be an integer >= 1, got "
                f"{self.upsample!r}."
            )
        if not self.warmup >= 0:
            raise ValueError(
                f"PeriodicSimulation: warmup must be >= 0 seconds, got {self.warmup}."
            )

    def warmup_samples(self, dt: float) -> int:
        """Warm-up length in original samples."""
        return int(math.ceil(self.warmup / dt - 1e-9))

    def path(self, u_period: Float[ArrayLike, " n"], dt: float) -> InputPath:
        """The fine-grid input path: warm-up (the periodic input continued backwards,
        over as many periods as it takes), then the period plus one sample (the start
        of the next period closes the last interval)."""
        u = np.asarray(u_period, dtype=float)
        fine = bandlimited_upsample(u, self.upsample)
        warm = self.warmup_samples(dt) * self.upsample
        repeats = -(-warm // fine.size) + 1  # ceil, plus the scored period
        values = np.concatenate(
            [np.tile(fine, repeats)[fine.size * repeats - warm - fine.size :], fine[:1]]
        )
        return InputPath(
            -warm * dt / self.upsample,
            dt / self.upsample,
            values,
            interpolation=self.interpolation,
        )

    def scored(self, path: InputPath, period: int) -> Array:
        """Indices of the fine-grid samples that fall on the period's original
        samples."""
        start = path.num_samples - 1 - period * self.upsample
        return start + self.upsample * jnp.arange(period)

    def output(
        self, model: AbstractHysteresisModel, path: InputPath, period: int
    ) -> Float[Array, " n"]:
        """The steady-state output over the period (traceable; `throw=False`)."""
        full = simulate(model, path, self.solver, throw=False)
        return full[self.scored(path, period)]

    def __call__(
        self, model: AbstractHysteresisModel, u_period: Float[ArrayLike, " n"], dt
    ) -> Float[np.ndarray, " n"]:
        """Steady-state output of `model` over one period `u_period` sampled at `dt`."""
        u = np.asarray(u_period, dtype=float)
        return np.asarray(_steady_output(self, model, self.path(u, float(dt)), u.size))


class SteadyOutput(eqx.Module):
    """The steady-state output of a model over one period of an input path:
    `SteadyOutput(simulation, path, period)(model)` (a module, so compiled callers
    reuse their compilation)."""

    simulation: PeriodicSimulation
    path: InputPath
    period: int = eqx.field(static=True)

    def __call__(self, model: AbstractHysteresisModel) -> Float[Array, " n"]:
        return self.simulation.output(model, self.path, self.period)


@eqx.filter_jit
def _steady_output(simulation, model, path, period):
    return SteadyOutput(simulation, path, period)(model)


def periodic_problem(
    space: ParameterSpace,
    period: Recording,
    simulation: PeriodicSimulation,
    *,
    samples: int | None = None,
) -> Problem:
    """The least-squares problem "steady-state output over `period` = its measured
    output", optionally over its first `samples` samples only (a cheaper copy for
    the swarm). Residuals are zero-weighted off the scored samples."""
    n = period.num_samples
    count = n if samples is None else int(samples)
    if not 2 <= count <= n:
        raise ValueError(f"periodic_problem: samples={samples!r} must lie in [2, {n}].")
    path = simulation.path(period.u, period.dt)
    keep = path.num_samples - (n - count) * simulation.upsample
    path = InputPath(
        path.t0, path.dt, path.values[:keep], interpolation=path.interpolation
    )
    # The scored samples: the `count` original samples after the warm-up.
    index = np.asarray(simulation.scored(path, count))
    measured = np.zeros(keep)
    weights = np.zeros(keep)
    measured[index] = period.y[:count]
    weights[index] = 1.0
    return Problem(
        space, path, jnp.asarray(measured), simulation.solver, jnp.asarray(weights)
    )


def oscillator_space(
    template: HystereticOscillator,
    recording: Recording,
    *,
    nu_free: bool = False,
) -> ParameterSpace:
    """`HystereticOscillator.default_bounds` for `recording` as a space (log-scaled,
    set by the data's scales, not by any known answer); `nu` stays at the
    template's value unless `nu_free` (then in [1, 3])."""
    box = template.default_bounds(DataScales.of(recording), nu_free=nu_free)
    return ParameterSpace(box.template, box.bounds, log_scale=box.log_scale)


def periodic_identifiability(
    model: AbstractHysteresisModel,
    period: Recording,
    simulation: PeriodicSimulation,
    *,
    free: tuple[str, ...],
    noise_sigma: float | None = None,
    threshold: float = 1e-6,
) -> Identifiability:
    """`identifiability` for a steady-state fit: the sensitivities of the scored
    period's output, the standard errors and correlations of the `free` parameters
    with sigma the noise of the fitted data (`noise_sigma`, default: the residual
    RMS)."""
    path = simulation.path(period.u, period.dt)
    return identifiability(
        model,
        SteadyOutput(simulation, path, period.num_samples),
        jnp.asarray(period.y),
        free=free,
        noise_sigma=noise_sigma,
        threshold=threshold,
    )


def fit_periodic(
    template: AbstractHysteresisModel,
    period: Recording,
    *,
    key: PRNGKeyArray,
    space: ParameterSpace,
    swarm: MPSO | None = MPSO(num_particles=64, num_iterations=150),
    prepolish: AbstractPolish | None = LevenbergMarquardtPolish(
        rtol=1e-6, atol=1e-8, max_steps=60, min_gain=1e-5
    ),
    polish: AbstractPolish | None = LevenbergMarquardtPolish(
        rtol=1e-6, atol=1e-8, max_steps=30, min_gain=1e-5
    ),
    simulation: PeriodicSimulation = PeriodicSimulation(),
    coarse_simulation: PeriodicSimulation = PeriodicSimulation(
        warmup=1.0, upsample=1, solver=RK4(substeps=2)
    ),
    swarm_samples: int | None = 1500,
    stall_iterations: int | None = 40,
    start: AbstractHysteresisModel | None = None,
    noise_sigma: float | None = None,
    analyse: bool = True,
    progress: bool = False,
    polish_device: jax.Device | None = None,
    throw: bool = True,
) -> Fit:
    """Fit `template` (its class and fixed parameters; the free ones are `space`'s)
    to the steady-state period `period` (e.g. `average_periods(...).recording`).

    Three stages, each seeded by the previous one:

    1. `swarm` (MPSO; None skips it) searches `space`'s unit box on a cheap problem:
       `coarse_simulation` (no upsampling, few RK4 substeps) over the first
       `swarm_samples` samples of the period (None: all of it);
    2. `prepolish` (None skips it) refines on the whole period, still with
       `coarse_simulation`: most of the descent, at a fraction of the cost;
    3. `polish` finishes on the whole period with the accurate `simulation`.

    - `start`: a model to refine from instead of, or beside, the swarm's best (the
      better of the two seeds stage 2).
    - `noise_sigma`: noise of `period`'s output, for the standard errors (default:
      the residual RMS); for an average of P periods, `PeriodicAverage.mean_sigma`.
    - `polish_device`: where stages 2-3 and the analysis run, as in `identify`.
    - `throw`: raise when the fit's status is not successful, as in `identify`.

    Returns a `Fit` whose `predicted` and `metrics` are over the period;
    `fit.polish` is the last polish stage that ran, `fit.timing` has every stage's
    seconds (`fit_s`: swarm start to fitted model, compilation included).
    """
    if swarm is None and start is None:
        raise ValueError(
            "fit_periodic: with swarm=None pass start=<model> to polish from."
        )
    if type(template) is not type(space.template):
        raise TypeError(
            f"fit_periodic: the space is for {type(space.template).__name__}, the "
            f"template is {type(template).__name__}."
        )
    space = space.with_template(template)  # its fixed parameters (e.g. nu) apply
    device = serial_device(polish_device, "polish_device")
    t_start = time.perf_counter()
    timing: dict[str, float] = {}
    seeds, swarm_result = starting_points(
        space,
        lambda: periodic_problem(
            space, period, coarse_simulation, samples=swarm_samples
        ),
        swarm,
        key,
        start,
        timing,
        stall_iterations=stall_iterations,
        chunk_size=10,
        progress=progress,
    )
    stages = [
        PolishStage(
            "prepolish", periodic_problem(space, period, coarse_simulation), prepolish
        ),
        PolishStage("polish", periodic_problem(space, period, simulation), polish),
    ]
    stages, seeds = moved_to((stages, seeds), device)
    with running_on(device):
        z, polish_result = refine(stages, seeds, timing)
        fitted = stages[0].problem.space.to_model(z)
        predicted = jnp.asarray(simulation(fitted, period.u, period.dt))
        metrics = error_metrics(period.y, predicted)
        timing["fit_s"] = time.perf_counter() - t_start
        report = None
        if analyse:
            t0 = time.perf_counter()
            report = periodic_identifiability(
                fitted, period, simulation, free=space.names, noise_sigma=noise_sigma
            )
            timing["identifiability_s"] = time.perf_counter() - t0
    timing["total_s"] = time.perf_counter() - t_start
    fit = Fit(
        model=fitted,
        predicted=predicted,
        metrics=metrics,
        swarm=swarm_result,
        polish=polish_result,
        identifiability=report,
        timing=timing,
        result=fit_status(swarm_result, polish_result, [predicted]),
    )
    if throw:
        raise_unless_successful(fit.result, "fit_periodic")
    return fit
