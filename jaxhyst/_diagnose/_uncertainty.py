"""Standard errors of fitted parameters from the output's sensitivities, for a
residual that is correlated in time."""

import numpy as np

from .._identification._identifiability import covariance
from ._locate import effective_samples


def standard_errors(jacobian: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """`errors_and_correlations`' standard errors."""
    return errors_and_correlations(jacobian, residual)[0]


def errors_and_correlations(
    jacobian: np.ndarray, residual: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Standard errors of the parameters whose output sensitivities are the columns
    of `jacobian` (samples x parameters), from sigma^2 (J^T J)^-1 (`covariance`)
    with sigma^2 the residual's variance inflated by N / N_eff (N_eff: the
    residual's effective number of independent samples, so a smooth, correlated
    residual does not pass for N independent ones). NaN for parameters that load
    on directions the record does not determine. Also their correlations."""
    n, p = jacobian.shape
    sigma2 = float(np.sum(residual**2)) / max(1, n - p)
    inflation = n / max(1.0, effective_samples(residual))
    return covariance(jacobian, sigma2 * inflation)
