"""The measurement noise of the synthetic records: a piezo stage's displacement
sensor and a structural test's load cell."""

import numpy as np


def _sensor_noise(
    rng: np.random.Generator, kind: str, sigma: float, num: int
) -> tuple[np.ndarray, str]:
    white = rng.standard_normal(num)
    if kind == "white":
        return sigma * white, "white Gaussian"
    if rng.random() < 0.5:
        phi, white_share = rng.uniform(0.9, 0.98), 0.0
    else:
        phi, white_share = rng.uniform(0.93, 0.98), rng.uniform(0.02, 0.08)
    drive = np.sqrt(1 - phi**2) * rng.standard_normal(num)
    drive[0] = rng.standard_normal()  # start in the stationary distribution
    import scipy.signal  # deferred: heavy import, needed only here

    ar = scipy.signal.lfilter([1.0], [1.0, -phi], drive)
    noise = sigma * (np.sqrt(1 - white_share) * ar + np.sqrt(white_share) * white)
    what = f"coloured AR(1), coefficient {phi:.3g}"
    if white_share:
        what += f", plus white noise carrying {white_share:.1%} of the variance"
    return noise, what


def _load_cell_noise(
    rng: np.random.Generator, kind: str, sigma: float, num: int
) -> tuple[np.ndarray, str]:
    white = rng.standard_normal(num)
    if kind == "white":
        return sigma * white, "white Gaussian"
    rho = rng.uniform(0.6, 0.9)
    drive = np.sqrt(1 - rho**2) * white
    drive[0] = white[0]  # start in the stationary distribution
    import scipy.signal  # deferred: heavy import, needed only here

    ar = np.asarray(scipy.signal.lfilter([1.0], [1.0, -rho], drive))
    return sigma * ar, f"coloured AR(1), coefficient {rho:.3g}"
