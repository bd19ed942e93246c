"""Error measures between a measured output `y` and a model output `yhat` (paper eq. 12
and eq. 15).

All functions are written with `jax.numpy`, so they work on NumPy or JAX arrays and
inside `jax.jit` / `jax.grad`. The normalised measures (MRD, NRMSD) divide by
y_max = max |y| of the **measured** output `y` (never of `yhat`), so a model cannot
improve its score by changing the scale it divides by. They are inf or nan when the
measured output is identically zero.
"""

import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from ._arrays import device_array


def _pair(
    fn: str, y: Float[ArrayLike, "..."], yhat: Float[ArrayLike, "..."]
) -> tuple[Float[Array, "..."], Float[Array, "..."]]:
    y = device_array(y)
    yhat = device_array(yhat)
    if y.shape != yhat.shape:
        raise ValueError(
            f"{fn}: y and yhat must have the same shape, got {y.shape} and "
            f"{yhat.shape}; compare the model output at the measured sample times."
        )
    if y.size == 0:
        raise ValueError(f"{fn}: y and yhat are empty; pass at least one sample.")
    dtype = jnp.result_type(y, yhat, float)
    return y.astype(dtype), yhat.astype(dtype)


def rmse(y: Float[ArrayLike, "..."], yhat: Float[ArrayLike, "..."]) -> Float[Array, ""]:
    """Root-mean-square error sqrt(mean((y - yhat)^2)) (eq. 12)."""
    y, yhat = _pair("rmse", y, yhat)
    return jnp.sqrt(jnp.mean((y - yhat) ** 2))


def mad(y: Float[ArrayLike, "..."], yhat: Float[ArrayLike, "..."]) -> Float[Array, ""]:
    """Maximum absolute deviation max |y - yhat| (eq. 15)."""
    y, yhat = _pair("mad", y, yhat)
    return jnp.max(jnp.abs(y - yhat))


def mrd(y: Float[ArrayLike, "..."], yhat: Float[ArrayLike, "..."]) -> Float[Array, ""]:
    """Maximum relative deviation MAD / y_max * 100, in percent, with y_max = max |y|
    of the measured `y` (eq. 15)."""
    y, yhat = _pair("mrd", y, yhat)
    return jnp.max(jnp.abs(y - yhat)) / jnp.max(jnp.abs(y)) * 100


def mae(y: Float[ArrayLike, "..."], yhat: Float[ArrayLike, "..."]) -> Float[Array, ""]:
    """Mean absolute error mean |y - yhat| (eq. 15)."""
    y, yhat = _pair("mae", y, yhat)
    return jnp.mean(jnp.abs(y - yhat))


def nrmsd(
    y: Float[ArrayLike, "..."], yhat: Float[ArrayLike, "..."]
) -> Float[Array, ""]:
    """Normalised RMS deviation RMSE / y_max (a fraction, not percent), with
    y_max = max |y| of the measured `y` (eq. 15)."""
    y, yhat = _pair("nrmsd", y, yhat)
    return jnp.sqrt(jnp.mean((y - yhat) ** 2)) / jnp.max(jnp.abs(y))


def error_metrics(
    y: Float[ArrayLike, "..."], yhat: Float[ArrayLike, "..."]
) -> dict[str, float]:
    """All five measures as Python floats, keyed "rmse", "mad", "mrd", "mae", "nrmsd".

    For reports; not traceable (use the individual functions inside `jit`/`grad`).
    """
    y, yhat = _pair("error_metrics", y, yhat)
    return {fn.__name__: float(value) for fn, value in zip(_MEASURES, _all(y, yhat))}


_MEASURES = (rmse, mad, mrd, mae, nrmsd)


@jax.jit
def _all(y, yhat) -> tuple[Array, ...]:
    # One program: called eagerly, the five measures compile five small ones.
    return tuple(fn(y, yhat) for fn in _MEASURES)
