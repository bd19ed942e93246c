"""Randomness of the synthetic records: NumPy generators seeded from JAX keys."""

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import PRNGKeyArray


def _rng(key: PRNGKeyArray, owner: str) -> np.random.Generator:
    """A NumPy generator seeded from a JAX key (typed or legacy uint32)."""
    if key is None or not hasattr(key, "dtype"):
        raise TypeError(
            f"{owner}: key must be a JAX PRNG key, e.g. jax.random.key(0), got "
            f"{type(key).__name__}; there is no default key."
        )
    if jnp.issubdtype(key.dtype, jax.dtypes.prng_key):
        data = jax.random.key_data(key)
    elif key.dtype == jnp.uint32 and key.shape == (2,):
        data = key
    else:
        raise TypeError(
            f"{owner}: key must be a JAX PRNG key, e.g. jax.random.key(0), got an "
            f"array of dtype {key.dtype} and shape {key.shape}."
        )
    return np.random.default_rng(np.asarray(data, dtype=np.uint32).ravel().tolist())


def _loguniform(rng: np.random.Generator, low: float, high: float) -> float:
    return float(np.exp(rng.uniform(np.log(low), np.log(high))))
