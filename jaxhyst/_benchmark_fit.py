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

from ._identify import (
    AbstractPolish,
    Fit,
    Identifiability,
    LevenbergMarquardtPolish,
    Problem,
    _swarm_objective,
    best_seed,
)
from ._inputs import AbstractInterpolation, CubicInterpolation, InputPath
from ._metrics import error_metrics
from ._models.base import AbstractHysteresisModel
from ._models.oscillator import HystereticOscillator
from ._params import ParameterSpace
from ._placement import moved_to, running_on, serial_device
from ._recording import Recording
from ._simulate import RK4, AbstractSimulationSolver, simulate
from ._swarm import MPSO, run_swarm


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


@eqx.filter_jit
def _steady_output(simulation, model, path, period):
    return simulation.output(model, path, period)


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
    """A log-scaled search space for `HystereticOscillator` set by the data's scales,
    not by any known answer: with k0 = rms(u)/rms(y) (a stiffness) and the Nyquist
    frequency f_N, stiffness and alpha in k0*[1e-2, 10], mass such that sqrt(k0/m)
    spans 1 Hz to f_N, damping/k0 from 1e-5 s to 1 s, and beta*gamma,
    beta*delta linear in +-5/rms(y). `nu` stays at the template's value unless
    `nu_free` (then in [1, 3])."""
    su = float(np.sqrt(np.mean(np.asarray(recording.u) ** 2)))
    sy = float(np.sqrt(np.mean(np.asarray(recording.y) ** 2)))
    if not (su > 0 and sy > 0):
        raise ValueError("oscillator_space: input and output must not be all zero.")
    k0 = su / sy
    nyquist = 0.5 * recording.sample_rate
    bounds = {
        "mass": (k0 / (2 * np.pi * nyquist) ** 2, k0 / (2 * np.pi * 1.0) ** 2),
        "damping": (1e-5 * k0, 1.0 * k0),
        "stiffness": (1e-2 * k0, 10 * k0),
        "alpha": (1e-2 * k0, 10 * k0),
        "beta_gamma": (-5 / sy, 5 / sy),
        "beta_delta": (-5 / sy, 5 / sy),
    }
    if nu_free:
        bounds["nu"] = (1.0, 3.0)
    return ParameterSpace(
        template, bounds, log_scale=["mass", "damping", "stiffness", "alpha"]
    )


def periodic_identifiability(
    model: AbstractHysteresisModel,
    period: Recording,
    simulation: PeriodicSimulation,
    *,
    free: tuple[str, ...],
    noise_sigma: float | None = None,
    threshold: float = 1e-6,
) -> Identifiability:
    """`identifiability` for a steady-state fit: the Jacobian of the scored period's
    output with respect to relative parameter changes (d y / d log|theta|), its
    singular values, and the standard errors and correlations of the `free`
    parameters from sigma^2 (J^T J)^-1, with sigma the noise of the fitted data
    (`noise_sigma`, default: the residual RMS)."""
    names = tuple(model.parameter_names)
    values = jnp.stack([jnp.asarray(v, float) for v in model.parameters().values()])
    scale = jnp.where(values != 0, values, 1.0)
    path = simulation.path(period.u, period.dt)
    n = period.num_samples

    def outputs(relative):
        new = eqx.tree_at(
            lambda m: [getattr(m, k) for k in names],
            model,
            list(values + relative * scale),
        )
        return simulation.output(new, path, n)

    jac = np.nan_to_num(
        np.asarray(jax.jit(jax.jacfwd(outputs))(jnp.zeros_like(values)))
    )
    norm = np.linalg.norm(jac, axis=0)
    safe = np.where(norm > 0, norm, 1.0)
    _, sv, vt = np.linalg.svd(jac / safe, full_matrices=False)
    relative = sv / sv[0] if sv[0] > 0 else sv
    null = []
    for s, v in zip(relative, vt):
        if s < threshold:
            v = v / safe
            v = v / v[np.argmax(np.abs(v))]
            null.append(
                {k: round(float(w), 6) for k, w in zip(names, v) if abs(w) > 1e-3}
            )
    residual = np.asarray(_steady_output(simulation, model, path, n)) - period.y
    if noise_sigma is None:
        noise_sigma = float(np.sqrt(np.sum(residual**2) / max(1, n - len(free))))
    columns = [names.index(k) for k in free]
    # Columns are d y / d(relative change) = (d y / d theta) * theta: back to theta.
    jf = jac[:, columns] / np.asarray(scale)[columns]
    jtj = jf.T @ jf
    if np.linalg.cond(jtj) < 1e14:
        cov = noise_sigma**2 * np.linalg.inv(jtj)
        se = np.sqrt(np.abs(np.diag(cov)))
        corr = cov / np.outer(se, se)
    else:
        se = np.full(len(free), np.nan)
        corr = np.full((len(free), len(free)), np.nan)
    return Identifiability(
        names,
        relative,
        null,
        tuple(free),
        corr,
        {k: float(e) for k, e in zip(free, se)},
        threshold,
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
    coarse = periodic_problem(space, period, coarse_simulation)
    seeds = []
    swarm_result = None
    if swarm is not None:
        short = periodic_problem(
            space, period, coarse_simulation, samples=swarm_samples
        )
        swarm_result = run_swarm(
            _swarm_objective,
            jnp.zeros(space.dimension),
            jnp.ones(space.dimension),
            swarm,
            key,
            args=short,
            chunk_size=10,
            progress=progress,
            stall_iterations=stall_iterations,
            stall_tolerance=1e-4 * float(np.max(np.abs(period.y))),
        )
        timing["swarm_s"] = swarm_result.wall_seconds
        seeds.append(swarm_result.best_x)
    if start is not None:
        seeds.append(jnp.clip(space.from_model(start), -0.5, 1.5))
    space, coarse, seeds = moved_to((space, coarse, seeds), device)
    with running_on(device):
        z = best_seed(coarse, seeds)
        polish_result = None
        if prepolish is not None:
            polish_result = prepolish.run(coarse, z)
            z = polish_result.z
            timing["prepolish_s"] = polish_result.wall_seconds
        if polish is not None:
            problem = periodic_problem(space, period, simulation)
            polish_result = polish.run(problem, z)
            z = polish_result.z
            timing["polish_s"] = polish_result.wall_seconds
        fitted = space.to_model(z)
        predicted = simulation(fitted, period.u, period.dt)
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
    return Fit(
        fitted,
        jnp.asarray(predicted),
        {k: float(v) for k, v in metrics.items()},
        swarm_result,
        polish_result,
        report,
        timing,
    )
