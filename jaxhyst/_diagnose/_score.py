"""The score test: output sensitivities, projection off the base, the noise model,
and the Lagrange-multiplier statistic."""

import math

import equinox as eqx
import numpy as np

from .._identification._identifiability import output_jacobian
from .._identification._problem import RecordSimulation
from .._models.base import AbstractHysteresisModel
from .._simulate import AbstractSimulationSolver, simulate


def jacobian(
    model: AbstractHysteresisModel, names, inputs, solver: AbstractSimulationSolver
) -> np.ndarray:
    """d output / d parameter for `names` (one compilation per model structure)."""
    return output_jacobian(model, names, RecordSimulation(inputs, solver))[0]


@eqx.filter_jit
def _predict_jit(model, inputs, solver):
    return simulate(model, inputs, solver, throw=False)


def predict(model: AbstractHysteresisModel, inputs, solver) -> np.ndarray:
    """The model's output at every sample (NaN/inf where it diverges)."""
    return np.asarray(_predict_jit(model, inputs, solver))


def project_off(base: np.ndarray, extra: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The part of `extra`'s columns that the base parameters cannot absorb."""
    bw = base * w[:, None]
    ew = extra * w[:, None]
    coef, *_ = np.linalg.lstsq(bw, ew, rcond=None)
    return ew - bw @ coef


def whitening_filter(noise: np.ndarray, order: int = 2) -> np.ndarray:
    """AR(order) coefficients of `noise` (least squares), used to pre-whiten the
    score test so that coloured sensor noise does not pass for physics."""
    x = noise - noise.mean()
    lagged = np.stack([x[order - k - 1 : x.size - k - 1] for k in range(order)], axis=1)
    coef, *_ = np.linalg.lstsq(lagged, x[order:], rcond=None)
    return coef


def whiten(x: np.ndarray, coef: np.ndarray) -> np.ndarray:
    out = np.array(x, dtype=float, copy=True)
    for k, a in enumerate(coef, start=1):
        out[k:] -= a * x[:-k]
    return out


def score_statistic(
    directions: np.ndarray, residual: np.ndarray, coef, sigma2
) -> float:
    """Lagrange-multiplier statistic of the pre-whitened residual along the
    pre-whitened directions: s^T (D^T D)^-1 s / sigma^2, ~ chi^2(dof) under no effect."""
    d = whiten(directions, coef)
    r = whiten(residual, coef)
    s = d.T @ r
    try:
        stat = float(s @ np.linalg.solve(d.T @ d, s)) / sigma2
    except np.linalg.LinAlgError:  # singular directions: no evidence along them
        stat = 0.0
    return max(stat, 0.0)


def max_canonical_correlation(a: np.ndarray, b: np.ndarray) -> float:
    qa, _ = np.linalg.qr(a)
    qb, _ = np.linalg.qr(b)
    return float(np.linalg.svd(qa.T @ qb, compute_uv=False).max(initial=0.0))


def moving_columns(cols: np.ndarray) -> np.ndarray:
    """`cols` without the columns that are zero (parameters that move nothing)."""
    norms = np.linalg.norm(cols, axis=0)
    return cols[:, norms > 1e-9 * max(float(norms.max(initial=0.0)), 1e-300)]


# The fewest samples an AR(2) is read from at a coarser stride.
MIN_STRIDED = 200


def _read_ar(series: np.ndarray) -> tuple[np.ndarray, float, float]:
    """The AR(2) of `series`, its innovation variance, and N_eff / N under it: the
    series' variance over the AR's long-run variance (clipped to [1e-4, 1])."""
    ar = whitening_filter(series)
    innovation = float(np.var(whiten(series, ar)[len(ar) :]))
    long_run = innovation / max(1e-12, (1 - float(np.sum(ar)))) ** 2
    return ar, innovation, min(1.0, max(1e-4, float(np.var(series)) / long_run))


class NoiseModel(eqx.Module):
    """The residual noise the score test and the held-out comparisons assume: an
    AR(2) colour read from what no candidate explains, its innovation variance,
    its standard deviation and how many independent samples a record is worth."""

    ar: np.ndarray
    innovation_var: float
    sd: float
    # N_eff / N for noise following the AR model.
    effective_ratio: float

    @classmethod
    def estimate(
        cls, unexplained: np.ndarray, *, across_strides: bool = False
    ) -> "NoiseModel":
        """The AR(2) noise model of `unexplained`.

        `across_strides`: also read the effective-sample ratio from every 2nd,
        4th, 8th, ... sample (while at least `MIN_STRIDED` remain) and keep the
        largest count. An AR(2) read at full density from a residual sampled far
        more densely than it varies (a quasi-static test in pseudo time) takes its
        smoothness for a near-unit root and counts a few effective samples in
        thousands, fewer the denser the record; read coarser, the same residual
        shows how many independent wiggles it has. For AR noise the strides agree
        (an AR(1) with coefficient a at stride s has coefficient a^s and s times
        fewer samples), so the count is unchanged. Families whose time axis only
        orders the samples switch it on (`AdoptionPolicy.noise_across_strides`)."""
        ar, innovation, ratio = _read_ar(unexplained)
        stride = 2
        while across_strides and unexplained.size // stride >= MIN_STRIDED:
            ratio = max(ratio, _read_ar(unexplained[::stride])[2] / stride)
            stride *= 2
        return cls(ar, innovation, float(np.std(unexplained)), ratio)

    def resolution(
        self, change: float, effective_samples: float, *, bound: float | None = None
    ) -> float:
        """How small a held-out MSE difference can be told from noise, for two fits
        whose outputs differ by `change` (rms): ~3 x its standard error
        2*sigma*change/sqrt(N_eff). `bound`: an upper bound on sigma (the held-out
        RMS of a fit: no model's residual is smaller than the noise)."""
        sd = self.sd if bound is None else min(self.sd, bound)
        return 3 * 2 * sd * change / math.sqrt(effective_samples)


def chi2():
    from scipy import stats  # deferred: scipy.stats costs ~0.5 s of import time

    return stats.chi2
