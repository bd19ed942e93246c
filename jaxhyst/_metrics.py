"""Error measures between a measured output `y` and a model output `yhat` (paper eq. 12
and eq. 15).

The five measures are written with `jax.numpy`, so they work on NumPy or JAX arrays
and inside `jax.jit` / `jax.grad`; `error_metrics`, for reports, computes the same
formulas with NumPy on the host. The normalised measures (MRD, NRMSD) divide by
y_max = max |y| of the **measured** output `y` (never of `yhat`), so a model cannot
improve its score by changing the scale it divides by. They are inf or nan when the
measured output is identically zero.
"""

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float


def _pair(fn: str, y, yhat, xp=jnp):
    """`y` and `yhat` as arrays of `xp` (`jax.numpy`, or NumPy for reports) in a
    common floating dtype, checked to have one non-empty shape."""
    if xp is np:
        y, yhat = np.asarray(y), np.asarray(yhat)
        dtype = np.result_type(y.dtype, yhat.dtype, np.float16)  # at least a float
    else:
        y, yhat = jnp.asarray(y), jnp.asarray(yhat)
        dtype = jnp.result_type(y, yhat, float)
    if y.shape != yhat.shape:
        raise ValueError(
            f"{fn}: y and yhat must have the same shape, got {y.shape} and "
            f"{yhat.shape}; compare the model output at the measured sample times."
        )
    if y.size == 0:
        raise ValueError(f"{fn}: y and yhat are empty; pass at least one sample.")
    return y.astype(dtype), yhat.astype(dtype)


# Each measure once, for an array namespace `xp`: `jax.numpy` for the public
# functions (traceable), NumPy for `error_metrics` (reports, on the host).


def _rmse(xp, y, yhat):
    return xp.sqrt(xp.mean((y - yhat) ** 2))


def _mad(xp, y, yhat):
    return xp.max(xp.abs(y - yhat))


def _mrd(xp, y, yhat):
    return _mad(xp, y, yhat) / xp.max(xp.abs(y)) * 100


def _mae(xp, y, yhat):
    return xp.mean(xp.abs(y - yhat))


def _nrmsd(xp, y, yhat):
    return _rmse(xp, y, yhat) / xp.max(xp.abs(y))


def rmse(y: Float[ArrayLike, "..."], yhat: Float[ArrayLike, "..."]) -> Float[Array, ""]:
    """Root-mean-square error sqrt(mean((y - yhat)^2)) (eq. 12)."""
    return _rmse(jnp, *_pair("rmse", y, yhat))


def mad(y: Float[ArrayLike, "..."], yhat: Float[ArrayLike, "..."]) -> Float[Array, ""]:
    """Maximum absolute deviation max |y - yhat| (eq. 15)."""
    return _mad(jnp, *_pair("mad", y, yhat))


def mrd(y: Float[ArrayLike, "..."], yhat: Float[ArrayLike, "..."]) -> Float[Array, ""]:
    """Maximum relative deviation MAD / y_max * 100, in percent, with y_max = max |y|
    of the measured `y` (eq. 15)."""
    return _mrd(jnp, *_pair("mrd", y, yhat))


def mae(y: Float[ArrayLike, "..."], yhat: Float[ArrayLike, "..."]) -> Float[Array, ""]:
    """Mean absolute error mean |y - yhat| (eq. 15)."""
    return _mae(jnp, *_pair("mae", y, yhat))


def nrmsd(
    y: Float[ArrayLike, "..."], yhat: Float[ArrayLike, "..."]
) -> Float[Array, ""]:
    """Normalised RMS deviation RMSE / y_max (a fraction, not percent), with
    y_max = max |y| of the measured `y` (eq. 15)."""
    return _nrmsd(jnp, *_pair("nrmsd", y, yhat))


def error_metrics(
    y: Float[ArrayLike, "..."], yhat: Float[ArrayLike, "..."]
) -> dict[str, float]:
    """All five measures as Python floats, keyed "rmse", "mad", "mrd", "mae", "nrmsd".

    For reports: computed with NumPy on the host, in the inputs' floating precision
    (no JAX program to compile); not traceable (use the individual functions inside
    `jit`/`grad`).
    """
    pair = _pair("error_metrics", y, yhat, np)
    with np.errstate(divide="ignore", invalid="ignore"):  # y == 0: inf or nan
        return {name: float(measure(np, *pair)) for name, measure in _MEASURES.items()}


_MEASURES = {"rmse": _rmse, "mad": _mad, "mrd": _mrd, "mae": _mae, "nrmsd": _nrmsd}
