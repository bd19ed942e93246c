"""Where one-trajectory work runs when the default device is an accelerator.

A swarm evaluates hundreds of particles per time step: wide work that an accelerator
runs well. The polish, the final simulation and the identifiability Jacobian integrate
one parameter set (or a handful of tangents) through a sequential `lax.scan` of
thousands of tiny steps; on a GPU each step costs a kernel launch (~20 us), so the
same work runs several times faster on the host CPU (measured on an H100: the
default fit's 20-step Levenberg-Marquardt polish took 20 s on the GPU).
"""

import contextlib
from collections.abc import Iterator
from typing import TypeVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np


Tree = TypeVar("Tree")


def serial_device(
    device: jax.Device | None, argument: str = "device"
) -> jax.Device | None:
    """The device for one-trajectory work: `device` if given, else the first CPU when
    the default device is not a CPU, else None (stay where JAX puts things).
    `argument` names the caller's argument in errors."""
    if device is not None:
        if not isinstance(device, jax.Device):
            raise TypeError(
                f"{argument} must be a jax.Device (e.g. jax.devices('cpu')[0]) or "
                f"None, got {type(device).__name__}."
            )
        return device
    if jax.devices()[0].platform == "cpu":
        return None
    try:
        return jax.devices("cpu")[0]
    except RuntimeError:  # no CPU backend in this process
        return None


@contextlib.contextmanager
def running_on(device: jax.Device | None) -> Iterator[None]:
    """Make `device` the default device inside the block (None: no change)."""
    if device is None:
        yield
        return
    with jax.default_device(device):
        yield


def moved_to(tree: Tree, device: jax.Device | None) -> Tree:
    """`tree` with its arrays copied to `device`, uncommitted (so the results can still
    be combined with arrays on any device, as if they had been made there); None
    returns `tree` unchanged."""
    if device is None:
        return tree
    arrays, static = eqx.partition(tree, eqx.is_array)
    with jax.default_device(device):
        arrays = jax.tree.map(_copied_here, arrays)
    return eqx.combine(arrays, static)


def _copied_here(x: jax.Array) -> jax.Array:
    if jnp.issubdtype(x.dtype, jax.dtypes.prng_key):
        data = jnp.asarray(np.asarray(jax.random.key_data(x)))
        return jax.random.wrap_key_data(data, impl=jax.random.key_impl(x))
    return jnp.asarray(np.asarray(x))
