"""The vectorisable power behind every |h|^n: accuracy against extended precision,
special values, and derivatives (its own and those of `safe_pow`)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxhyst._fast_pow import exp2, log2_positive, positive_pow
from jaxhyst._smoothing import safe_pow


DTYPES = [np.float64, np.float32]


def _eps(dtype):
    return float(np.finfo(dtype).eps)


@pytest.mark.parametrize("dtype", DTYPES)
def test_log2_within_two_ulps_over_the_normal_range(dtype):
    info = np.finfo(dtype)
    rng = np.random.default_rng(0)
    x = np.concatenate(
        [
            np.exp(rng.uniform(np.log(info.tiny), np.log(info.max), 50_000)),
            rng.uniform(0.5, 2.0, 50_000),  # around the reduction's seams
            [info.tiny, info.max, 1.0, 2.0, 0.5, np.sqrt(0.5), np.sqrt(2.0)],
        ]
    ).astype(dtype)
    got = np.asarray(jax.jit(log2_positive)(x), np.longdouble)
    exact = np.log2(x.astype(np.longdouble))
    error = np.abs(got - exact) / np.maximum(np.abs(exact), 1)
    assert float(error.max()) < 2 * _eps(dtype)
    assert float(log2_positive(jnp.asarray(np.inf, dtype))) == np.inf


@pytest.mark.parametrize("dtype", DTYPES)
def test_exp2_within_two_ulps_and_overflows_like_xla(dtype):
    info = np.finfo(dtype)
    rng = np.random.default_rng(1)
    y = np.concatenate(
        [
            rng.uniform(info.minexp, info.maxexp, 50_000),
            rng.uniform(-2, 2, 50_000),
            [0.0, 1.0, -1.0, 0.5, -0.5, info.maxexp - 1e-3],
        ]
    ).astype(dtype)
    got = np.asarray(jax.jit(exp2)(y), np.longdouble)
    exact = np.exp2(y.astype(np.longdouble))
    normal = (exact >= info.tiny) & (exact <= info.max)
    error = np.abs(got[normal] - exact[normal]) / exact[normal]
    assert float(error.max()) < 2 * _eps(dtype)
    # Beyond the range: the same inf / 0 as XLA's own exp2 (XLA flushes subnormals).
    wide = np.concatenate(
        [rng.uniform(-3 * info.maxexp, 3 * info.maxexp, 20_000), [1e30, -1e30]]
    ).astype(dtype)
    ours, xla = np.asarray(exp2(wide)), np.asarray(jnp.exp2(wide))
    np.testing.assert_array_equal(np.isinf(ours), np.isinf(xla))
    np.testing.assert_array_equal(ours == 0, xla == 0)


@pytest.mark.parametrize("dtype", DTYPES)
def test_power_error_is_that_of_exp_of_log(dtype):
    """exp2(n log2 b) loses |log2(b^n)| ulps at most (the rounding of the product);
    the bound here is 4 ulps per unit of |log2 result|, at least 4 ulps."""
    rng = np.random.default_rng(2)
    base = np.exp(rng.uniform(-20, 20, 50_000)).astype(dtype)
    exponent = rng.uniform(1, 4, 50_000).astype(dtype)
    got = np.asarray(jax.jit(positive_pow)(base, exponent), np.longdouble)
    exact = np.power(base.astype(np.longdouble), exponent.astype(np.longdouble))
    ok = (exact > np.finfo(dtype).tiny) & (exact < np.finfo(dtype).max)
    scale = np.maximum(1, np.abs(np.log2(exact[ok])))
    error = np.abs(got[ok] - exact[ok]) / exact[ok] / scale
    assert float(error.max()) < 4 * _eps(dtype)


def test_derivatives_of_log2_and_exp2_match_finite_differences():
    x = jnp.array([1e-3, 0.37, 1.0, 5.5, 300.0])
    for f in (log2_positive, exp2):
        grad = jax.vmap(jax.grad(f))(x)
        step = 1e-6 * jnp.maximum(x, 1.0) if f is exp2 else 1e-6 * x
        central = (f(x + step) - f(x - step)) / (2 * step)
        np.testing.assert_allclose(grad, central, rtol=1e-8)
    # Second derivatives exist too (custom rules all the way down).
    np.testing.assert_allclose(
        jax.vmap(jax.grad(jax.grad(exp2)))(x), np.log(2) ** 2 * np.exp2(x), rtol=1e-12
    )


def test_safe_pow_values_and_gradients():
    base = jnp.array([0.0, 1e-300, 1e-3, 0.7, 1.0, 3.0, 1e5])
    for n in (1.0, 1.5, 2.0, 3.7):
        expected = np.power(np.asarray(base), n)
        got = np.asarray(safe_pow(base, n))
        # exp-of-log rounding: a few ulps per unit of |log2 result| (see above).
        scale = np.maximum(1, np.abs(np.log2(expected, where=expected > 0, out=None)))
        scale = np.where(expected > 0, scale, 1)
        assert np.all(np.abs(got - expected) <= 4 * _eps(np.float64) * scale * expected)
        db, dn = jax.vmap(jax.grad(safe_pow, argnums=(0, 1)), in_axes=(0, None))(
            base, n
        )
        assert np.all(np.isfinite(db)) and np.all(np.isfinite(dn))
        inner = np.asarray(base) > 1e-200
        b = np.asarray(base)[inner]
        np.testing.assert_allclose(
            np.asarray(db)[inner], n * b ** (n - 1), rtol=1e-13, atol=1e-300
        )
        np.testing.assert_allclose(np.asarray(dn)[inner], b**n * np.log(b), rtol=1e-13)
        # At zero: d/db is 1 for n == 1 and 0 above; d/dn is 0.
        assert float(db[0]) == (1.0 if n == 1 else 0.0) and float(dn[0]) == 0.0
    # The value with and without a derivative requested agree to rounding.
    value, _ = jax.jvp(safe_pow, (base, 2.5), (jnp.ones_like(base), 0.0))
    np.testing.assert_allclose(value, safe_pow(base, 2.5), rtol=8 * _eps(np.float64))


def test_float32_stays_float32():
    x = jnp.linspace(0.1, 10, 7, dtype=jnp.float32)
    assert log2_positive(x).dtype == jnp.float32
    assert exp2(x).dtype == jnp.float32
    assert safe_pow(x, jnp.float32(1.5)).dtype == jnp.float32
