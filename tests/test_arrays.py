"""Building models, input paths, parameter spaces and swarm settings from host values
(Python numbers, NumPy arrays) compiles nothing, and gives the arrays `jnp.asarray`
gives: every command builds these at its start, and each small conversion program
cost about 10 ms there."""

import jax
import jax.numpy as jnp
import numpy as np
from helpers import lowered_while

import jaxhyst as jh
from jaxhyst._arrays import device_array


def test_host_values_become_arrays_without_compiling():
    # Shapes no other test uses, so that nothing compiled earlier hides a compile.
    values = np.sin(np.arange(13) / 3.0)

    def build():
        path = jh.InputPath(0.0, 0.01, values, channels=np.ones((1, 13)))
        model = jh.PiezoBoucWen(1, 2.0, 0.5, np.float64(3.0), 4.0, 1.5)
        swarm = jh.MPSO(num_particles=7, num_iterations=3, velocity_limit=0.3)
        space = jh.ParameterSpace(
            model, {"k1": (0.1, 9.0), "beta1": (0.5, 7.0), "n": (1.0, 3.0)}
        )
        return path, model, swarm, space

    (path, model, swarm, space), lowered = lowered_while(build)
    assert lowered == []
    np.testing.assert_array_equal(path.values, values)
    for array in (path.values, path.dt, model.k1, model.A1, swarm.c1, space.lower):
        assert isinstance(array, jax.Array)
        assert array.dtype == jnp.float64 and not array.weak_type
    assert space.frozen.dtype == jnp.bool_
    assert float(model.k1) == 1.0 and float(space.upper[1]) == 7.0


def test_device_array_matches_jnp_asarray():
    for value, dtype in [(1.5, None), ([1, 2], jnp.float64), (np.ones(3), None)]:
        expected = jnp.asarray(np.asarray(value), dtype=dtype)
        got = device_array(value, dtype)
        assert got.dtype == expected.dtype and got.weak_type == expected.weak_type
        np.testing.assert_array_equal(got, expected)
    # JAX arrays and tracers go through jnp.asarray.
    traced = jax.jit(lambda x: device_array(x, jnp.float32))(jnp.arange(3.0))
    assert traced.dtype == jnp.float32
