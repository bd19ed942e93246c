"""Standard errors of fitted parameters from the output's sensitivities, for a
residual that is correlated in time."""

import numpy as np

from ._locate import effective_samples


# Directions of the column-scaled Jacobian with a relative singular value below
# this are not determined by the record; parameters loading on them get NaN.
UNDETERMINED = 1e-7
# A parameter loads on a direction when its weight in it exceeds this.
LOADING = 0.1


def standard_errors(jacobian: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """Standard errors of the parameters whose output sensitivities are the columns
    of `jacobian` (samples x parameters), from sigma^2 (J^T J)^-1 with sigma^2 the
    residual's variance and the covariance inflated by N / N_eff (N_eff: the
    residual's effective number of independent samples, so a smooth, correlated
    residual does not pass for N independent ones). NaN for parameters that load
    on directions the record does not determine."""
    n, p = jacobian.shape
    if p == 0:
        return np.zeros(0)
    norms = np.linalg.norm(jacobian, axis=0)
    safe = np.where(norms > 0, norms, 1.0)
    _, singular, vt = np.linalg.svd(jacobian / safe, full_matrices=False)
    relative = singular / singular[0] if singular[0] > 0 else np.zeros_like(singular)
    good = relative > UNDETERMINED
    cov_scaled = (vt[good].T / singular[good] ** 2) @ vt[good]
    sigma2 = float(np.sum(residual**2)) / max(1, n - p)
    inflation = n / max(1.0, effective_samples(residual))
    se = np.sqrt(np.abs(np.diag(cov_scaled)) * sigma2 * inflation) / safe
    loads = np.any(np.abs(vt[~good]) > LOADING, axis=0) | (norms == 0)
    return np.where(loads, np.nan, se)
