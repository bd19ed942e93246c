"""`x ** p` for positive x as exp2(p * log2(x)), written in vectorisable arithmetic.

Every Bouc-Wen vector field evaluates |h|^n, four times per RK4 step, and on CPU that
power dominates the cost of a swarm: XLA's float64 `log` is a scalar libm call (about
4.7 ns per element against 1 ns here, measured on the AVX-512 CI machine) and, more
important, the chain of four powers per step is latency-bound. Here log2 and exp2 are
polynomials (Estrin's scheme: a short dependency chain) after exact range reduction
through the floating-point bits, so XLA fuses and vectorises them with the rest of the
RK4 step.

Accuracy is that of the dtype: the polynomials are Chebyshev interpolants of
log2(1 + f) on [sqrt(1/2) - 1, sqrt(2) - 1] and of 2**r on [-1/2, 1/2], computed in
40-digit arithmetic (`docs/fast_pow_coefficients.py` regenerates them); their error
is below the dtype's rounding (the tests compare against long double).
"""

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float


# (centre, half width, monomial coefficients in x = (argument - centre) / half width)
_LOG2_1P = {
    "float64": (
        0.060660171779821276,
        0.35355339059327373,
        (
            0.08496250072115617,
            0.48089834696298756,
            -0.08014972449383123,
            0.017811049887534854,
            -0.00445276247188487,
            0.0011874033254731411,
            -0.00032983425706102095,
            9.423836275288799e-05,
            -2.7486189233080632e-05,
            8.144036514492229e-06,
            -2.4432105919584336e-06,
            7.404308282113254e-07,
            -2.2624357850144054e-07,
            6.948218964585523e-08,
            -2.1505228723152542e-08,
            6.860445387170143e-09,
            -2.144879695574202e-09,
            5.379806030774528e-10,
            -1.688974277242841e-10,
            1.1329319197865094e-10,
            -3.596967264705169e-11,
        ),
    ),
    "float32": (
        0.060660171779821276,
        0.35355339059327373,
        (
            0.08496249464828853,
            0.4808983488100604,
            -0.08014942141662693,
            0.017810957708578573,
            -0.0044551633642752695,
            0.0011881334373029702,
            -0.0003232564115184347,
            9.22386703170409e-05,
            -3.464675674819862e-05,
            1.0319333233477627e-05,
        ),
    ),
}
_EXP2 = {
    "float64": (
        0.0,
        0.5,
        (
            1.0,
            0.34657359027997264,
            0.060056626739775396,
            0.006938013583102703,
            0.0006011330692242035,
            4.166736920752022e-05,
            2.40680163495693e-06,
            1.1916198313716229e-07,
            5.162278334340772e-09,
            1.9879017749480353e-10,
            6.908392868445821e-12,
            2.175692338054719e-13,
        ),
    ),
    "float32": (
        0.0,
        0.5,
        (
            1.0,
            0.3465736033514163,
            0.060056627305721894,
            0.0069379090333378775,
            0.0006011285424077898,
            4.187633805504949e-05,
            2.4158507341514264e-06,
        ),
    ),
}
# integer type, mantissa bits, exponent bias
_LAYOUT = {"float64": (np.int64, 52, 1023), "float32": (np.int32, 23, 127)}


def _estrin(x: Array, coefficients: tuple[float, ...]) -> Array:
    """sum_i coefficients[i] * x**i with a dependency chain of log2(degree) levels."""
    terms = [jnp.asarray(c, x.dtype) for c in coefficients]
    power = x
    while len(terms) > 1:
        if len(terms) % 2:
            terms.append(jnp.zeros((), x.dtype))
        terms = [terms[i] + terms[i + 1] * power for i in range(0, len(terms), 2)]
        power = power * power
    return terms[0]


def _unscaled(coefficients, half_width):
    """Coefficients of p(d / half_width) as a polynomial in d: the polynomial then
    takes the offset from the centre directly (one multiply less on the chain)."""
    return tuple(c / half_width**i for i, c in enumerate(coefficients))


def _supported(x: Array) -> bool:
    return x.dtype.name in _LAYOUT


@jax.custom_jvp
def log2_positive(x: Float[ArrayLike, "..."]) -> Float[Array, "..."]:
    """log2(x) for normal x > 0 (inf gives inf). Zero, subnormal (XLA's CPU backend
    flushes them to zero), negative and NaN inputs give meaningless finite numbers:
    callers select those out."""
    x = jnp.asarray(x)
    if not _supported(x):
        return jnp.log2(x)
    int_type, mantissa_bits, bias = _LAYOUT[x.dtype.name]
    centre, half_width, coefficients = _LOG2_1P[x.dtype.name]
    one = int(np.array(1.0, x.dtype).view(int_type))
    low = int(np.array(np.sqrt(0.5), x.dtype).view(int_type))
    # Write x = 2**k * m with m in [sqrt(1/2), sqrt(2)) by moving the exponent field.
    bits = jax.lax.bitcast_convert_type(x, int_type) + (one - low)
    k = ((bits >> mantissa_bits) - bias).astype(x.dtype)
    mantissa = jax.lax.bitcast_convert_type(
        (bits & ((1 << mantissa_bits) - 1)) + low, x.dtype
    )
    offset = mantissa - (1 + centre)
    result = k + _estrin(offset, _unscaled(coefficients, half_width))
    return jnp.where(x == jnp.inf, x, result)


@log2_positive.defjvp
def _log2_positive_jvp(primals, tangents):
    (x,), (dx,) = primals, tangents
    x = jnp.asarray(x)
    return log2_positive(x), dx / (x * np.log(2.0).astype(x.dtype))


@jax.custom_jvp
def exp2(y: Float[ArrayLike, "..."]) -> Float[Array, "..."]:
    """2**y for finite y, overflowing to inf and underflowing through the
    subnormals to 0 like `jnp.exp2`."""
    y = jnp.asarray(y)
    if not _supported(y):
        return jnp.exp2(y)
    int_type, mantissa_bits, bias = _LAYOUT[y.dtype.name]
    _, half_width, coefficients = _EXP2[y.dtype.name]
    whole = jnp.round(y)
    fraction = _estrin(y - whole, _unscaled(coefficients, half_width))
    # 2**whole as two powers of two, each inside the normal range, so that results
    # near overflow and in the subnormal range come out right.
    limit = bias + mantissa_bits + 2
    whole = jnp.clip(whole, -limit, bias + 2).astype(int_type)
    half = whole >> 1

    def power_of_two(e):
        return jax.lax.bitcast_convert_type((e + bias) << mantissa_bits, y.dtype)

    return fraction * power_of_two(half) * power_of_two(whole - half)


@exp2.defjvp
def _exp2_jvp(primals, tangents):
    (y,), (dy,) = primals, tangents
    value = exp2(y)
    return value, value * np.log(2.0).astype(value.dtype) * dy


def positive_pow(
    base: Float[ArrayLike, "..."], exponent: Float[ArrayLike, "..."]
) -> Float[Array, "..."]:
    """`base ** exponent` for base > 0 and finite exponent (float32 / float64)."""
    return exp2(exponent * log2_positive(base))
