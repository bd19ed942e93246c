"""The search that sets a concealed effect's size (shared by both families).

Each effect's size is *set*: its coefficient is rescaled (exactly where the output
is linear in it, by a safeguarded secant search where it is not) until the RMS of
(y with the effect - y without it) equals the requested number of noise sigmas.
"""

import math
from collections.abc import Callable

import equinox as eqx
import numpy as np


# A form that reaches less than this share of the target size gives way to the next.
_REACHED = 0.98

# A sizer returns (field, component, RMS reached, form, description).
_Sized = tuple[str, eqx.Module, float, str, str]


def _first_reaching(target: float, forms: list[Callable[[], _Sized]]) -> _Sized:
    """The first form that reaches the target size, else the one that came closest
    (a form is capped where its physics would turn unrealistic)."""
    best = forms[0]()
    for form in forms[1:]:
        if best[2] >= _REACHED * target:
            break
        sized = form()
        best = sized if sized[2] > best[2] else best
    return best


def _in_order(rng: np.random.Generator, forms: list) -> list:
    """The forms with a random first choice, the others as fallbacks."""
    first = int(rng.integers(len(forms)))
    return forms[first:] + forms[:first]


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def _solve_size(
    measure: Callable[[float], float],
    target: float,
    start: float,
    *,
    linear: bool,
    most: float = math.inf,
) -> tuple[float, float]:
    """A coefficient p > 0 with measure(p) = target (an RMS), and the RMS reached.

    Exact rescaling where the effect is linear in p; otherwise a secant search in
    log-log coordinates, safeguarded by bisection once the target is bracketed, and
    capped at `most` (the RMS reached is then below the target)."""
    r = measure(start)
    if not r > 0:
        raise RuntimeError("an effect left the output unchanged; cannot size it")
    if linear:
        return start * target / r, target
    points = [(start, r)]
    low = high = None
    p = start
    for _ in range(12):
        if abs(r / target - 1) < 0.005:
            break
        if r < target:
            low = p if low is None else max(low, p)
        else:
            high = p if high is None else min(high, p)
        order = 1.0
        if len(points) >= 2:
            (p0, r0), (p1, r1) = points[-2], points[-1]
            if p0 != p1 and r0 > 0 and r1 > 0:
                order = float(np.clip(np.log(r1 / r0) / np.log(p1 / p0), 0.2, 5.0))
        step = p * (target / r) ** (1 / order)
        if low is not None and high is not None and not low < step < high:
            step = math.sqrt(low * high)
        if step >= most:
            if p >= most:
                break  # capped: the largest allowed size is not enough
            step = most
        p = step
        r = measure(p)
        points.append((p, r))
    return min(points, key=lambda pr: abs(math.log(pr[1] / target)))
