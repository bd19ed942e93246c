"""The check shared by the functions that take a sampled series on a uniform grid."""

import numpy as np
from jaxtyping import ArrayLike


def uniform_series(
    owner: str, times: ArrayLike, values: ArrayLike, *, name: str, minimum: int
) -> tuple[np.ndarray, np.ndarray, float]:
    """(times, values, dt) as float arrays, after checking that both are 1-D, of
    equal length >= `minimum`, finite, and that `times` is uniformly spaced and
    increasing; `name` is how `owner`'s errors call `values`."""
    t = np.asarray(times, dtype=float)
    v = np.asarray(values, dtype=float)
    if t.ndim != 1 or v.shape != t.shape or t.size < minimum:
        raise ValueError(
            f"{owner}: times and {name} must be 1-D of equal length >= {minimum}, got "
            f"shapes {t.shape} and {v.shape}."
        )
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
        raise ValueError(f"{owner}: times and {name} must be finite.")
    steps = np.diff(t)
    dt = float(np.mean(steps))
    if not dt > 0 or np.max(np.abs(steps - dt)) > 1e-6 * dt:
        raise ValueError(
            f"{owner}: times must be uniformly spaced and increasing; resample the "
            f"{name} first."
        )
    return t, v, dt
