"""Sign and absolute-value rules used by every model term that contains sign(x) or |x|.

A model holds one smoothing rule and routes *every* sign and |.| through it, so the
vector field is consistently exact (non-differentiable at 0) or consistently smooth.
"""

import abc

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from ._fast_pow import positive_pow


@jax.custom_jvp
def _safe_pow(base, exponent):
    """`base ** exponent` for `base >= 0`, `exponent >= 1`, finite in value and in
    both derivatives at `base == 0` (a naive `exp(exponent * log(base))` is NaN there).

    Uses exp2(exponent * log2(base)) in vectorisable arithmetic (`_fast_pow`), which
    XLA evaluates far faster than `jnp.power` or `jnp.exp`/`jnp.log` in float64.
    """
    base = jnp.asarray(base)
    positive = base > 0
    safe_base = jnp.where(positive, base, 1)
    return jnp.where(positive, positive_pow(safe_base, exponent), 0)


@_safe_pow.defjvp
def _safe_pow_jvp(primals, tangents):
    # Derivative programs (the polish, Jacobians) are compiled many times and run
    # few steps, so they use XLA's exp/log, which compile faster than the
    # polynomials; the values agree to a few units in the last place.
    base, exponent = primals
    d_base, d_exponent = tangents
    base = jnp.asarray(base)
    positive = base > 0
    safe_base = jnp.where(positive, base, 1)
    log_base = jnp.log(safe_base)
    value = jnp.where(positive, jnp.exp(exponent * log_base), 0)
    # d/dbase b^n = n b^(n-1): at b = 0 this is 1 for n == 1 and 0 for n > 1.
    at_zero = jnp.where(exponent == 1, 1.0, 0.0)
    d_value_d_base = exponent * jnp.where(
        positive, jnp.exp((exponent - 1) * log_base), at_zero
    )
    # d/dn b^n = b^n log b, whose limit at b = 0 is 0.
    d_value_d_exponent = jnp.where(positive, value * log_base, 0)
    return value, d_value_d_base * d_base + d_value_d_exponent * d_exponent


# One nested program: traced once per argument type per process, where inline its
# polynomials (about a hundred operations) were traced again at every |h|^n of every
# vector field, and under every derivative and batch. XLA inlines the call.
safe_pow = eqx.filter_jit(_safe_pow)


class AbstractSmoothing(eqx.Module):
    """How a model evaluates sign(x) and |x|.

    `abs(x)` is always `x * sign(x)`, so both are smoothed the same way.
    """

    @abc.abstractmethod
    def sign(self, x: Float[ArrayLike, "..."]) -> Float[Array, "..."]:
        """The (possibly smoothed) sign of `x`."""

    def abs(self, x: Float[ArrayLike, "..."]) -> Float[Array, "..."]:
        """The (possibly smoothed) absolute value of `x`, equal to `x * sign(x)`."""
        return jnp.asarray(x) * self.sign(x)

    def abs_pow(
        self, x: Float[ArrayLike, "..."], exponent: Float[ArrayLike, "..."]
    ) -> Float[Array, "..."]:
        """`|x| ** exponent`, finite in value and gradient at `x == 0` for exponent >= 1."""
        return safe_pow(self.abs(x), exponent)


class ExactSign(AbstractSmoothing):
    """The exact `sign` and `|.|`. Use for simulation and for the swarm, which needs no
    gradients; switch to a smooth rule before gradient-based refinement."""

    def sign(self, x):
        return jnp.sign(x)


class TanhSign(AbstractSmoothing):
    """`sign(x) ~ tanh(x / width)`.

    `width` is in the units of the argument (input rate or hysteretic variable);
    choose it well below the typical magnitude (1e-3 of it is a safe start).
    """

    width: float | Float[Array, ""]

    def __check_init__(self):
        if isinstance(self.width, (int, float)) and not self.width > 0:
            raise ValueError(
                f"TanhSign(width={self.width}): width must be positive; use "
                "ExactSign() for the unsmoothed sign."
            )

    def sign(self, x):
        return jnp.tanh(x / self.width)


class AlgebraicSign(AbstractSmoothing):
    """`sign(x) ~ x / sqrt(x**2 + width**2)`: cheaper than tanh, with heavier tails."""

    width: float | Float[Array, ""]

    def __check_init__(self):
        if isinstance(self.width, (int, float)) and not self.width > 0:
            raise ValueError(
                f"AlgebraicSign(width={self.width}): width must be positive; use "
                "ExactSign() for the unsmoothed sign."
            )

    def sign(self, x):
        x = jnp.asarray(x)
        return x * jax.lax.rsqrt(x * x + self.width**2)
