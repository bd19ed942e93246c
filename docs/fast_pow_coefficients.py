"""Regenerate the polynomial coefficients of `jaxhyst/_fast_pow.py`.

Each polynomial is the Chebyshev interpolant (at Chebyshev points of the first kind)
of its function on its interval, computed in 40-digit arithmetic and converted to
monomial coefficients in x = (argument - centre) / half width:

- log2(1 + f) on [sqrt(1/2) - 1, sqrt(2) - 1], degree 20 (float64) and 9 (float32);
- 2**r on [-1/2, 1/2], degree 11 (float64) and 6 (float32).

The degrees are the smallest whose interpolation error is below the dtype's rounding
(the script prints the maximum error against mpmath on a fine grid). Needs mpmath
(`pip install mpmath`); run `python docs/fast_pow_coefficients.py`.
"""

import mpmath as mp
import numpy as np


mp.mp.dps = 40


def chebyshev_monomials(func, a, b, degree):
    """(centre, half width, monomial coefficients in x) of the interpolant."""
    centre, half = (mp.mpf(a) + b) / 2, (mp.mpf(b) - a) / 2
    m = degree + 1
    nodes = [mp.cos(mp.pi * (2 * j + 1) / (2 * m)) for j in range(m)]
    values = [func(centre + half * x) for x in nodes]
    cheb = []
    for k in range(m):
        s = sum(values[j] * mp.cos(k * mp.pi * (2 * j + 1) / (2 * m)) for j in range(m))
        cheb.append(s * 2 / m if k else s / m)
    # T_k as monomials (T_0 = 1, T_1 = x, T_k = 2x T_{k-1} - T_{k-2}).
    basis = [[mp.mpf(1)], [mp.mpf(0), mp.mpf(1)]]
    for k in range(2, m):
        t = [mp.mpf(0)] + [2 * c for c in basis[k - 1]]
        for i, c in enumerate(basis[k - 2]):
            t[i] -= c
        basis.append(t)
    monomial = [mp.mpf(0)] * m
    for k in range(m):
        for i, c in enumerate(basis[k]):
            monomial[i] += cheb[k] * c
    return float(centre), float(half), tuple(float(c) for c in monomial)


def max_error(func, a, b, fit, dtype):
    centre, half, coefficients = fit
    grid = np.linspace(a, b, 4001)
    x = ((grid - centre) / half).astype(dtype)
    value = np.zeros_like(x)
    for c in coefficients[::-1]:
        value = value * x + dtype(c)
    exact = np.array([float(func(mp.mpf(float(g)))) for g in grid])
    return float(np.max(np.abs(value - exact)))


def main():
    log2_1p = lambda f: mp.log(1 + f) / mp.log(2)  # noqa: E731
    exp2 = lambda r: mp.power(2, r)  # noqa: E731
    low, high = float(mp.sqrt(0.5) - 1), float(mp.sqrt(2) - 1)
    tables = {
        "_LOG2_1P": (log2_1p, low, high, {"float64": 20, "float32": 9}),
        "_EXP2": (exp2, -0.5, 0.5, {"float64": 11, "float32": 6}),
    }
    for name, (func, a, b, degrees) in tables.items():
        print(f"{name} = {{")
        for dtype_name, degree in degrees.items():
            fit = chebyshev_monomials(func, a, b, degree)
            error = max_error(func, a, b, fit, np.dtype(dtype_name).type)
            print(f"    # degree {degree}: max error {error:.2e}")
            print(f"    {dtype_name!r}: {fit!r},")
        print("}")


if __name__ == "__main__":
    main()
