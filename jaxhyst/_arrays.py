"""JAX arrays made from host values without compiling anything."""

from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np
from jax.core import Tracer
from jaxtyping import Array, ArrayLike


def device_array(value: ArrayLike | Sequence[float | bool], dtype=None) -> Array:
    """`jnp.asarray(value, dtype)`, except that a host value (Python numbers, lists
    of them, NumPy arrays) is converted by NumPy and transferred: `jnp.asarray`
    compiles a small program for each new shape and dtype it converts, about 10 ms
    each, which every command paid again at its start. JAX arrays and tracers go
    through `jnp.asarray`. The result is strongly typed, its dtype canonical (float32
    where 64-bit types are off)."""
    if isinstance(value, (jax.Array, Tracer)):
        return jnp.asarray(value, dtype=dtype)
    return jax.device_put(np.asarray(value, dtype=dtype))
