"""Where a residual lives: branches, reversals, extremes, rates, holds, time, frequency."""

from typing import Any

import numpy as np


# A category "stands out" when its residual RMS is at least this multiple of the
# overall RMS: 1.25x is 56 % more power than average, well above the scatter of a
# category's RMS for an evenly spread residual of a few hundred independent samples.
CONCENTRATED = 1.25
# Categories covering at most this share of the samples are too small to judge.
MIN_FRACTION = 0.01
# A part of the residual (its slow trend, its even part) "carries" the residual
# when its RMS is at least this share of the overall RMS (a quarter of the power).
CARRIES = 0.5


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def effective_samples(residual: np.ndarray, max_lag: int | None = None) -> float:
    """Effective number of independent samples of a correlated residual,
    N / (1 + 2*sum of autocorrelations up to the first non-positive one)."""
    r = residual - residual.mean()
    n = r.size
    var = float(np.dot(r, r)) / n
    if var == 0:
        return float(n)
    lags = max_lag or min(n // 4, 5000)
    spectrum = np.fft.rfft(r, 2 * n)
    acov = np.fft.irfft(spectrum * np.conj(spectrum))[: lags + 1] / n
    rho = acov / acov[0]
    total = 0.0
    for k in range(1, lags + 1):
        if rho[k] <= 0:
            break
        total += rho[k]
    return n / (1 + 2 * total)


def locate(t: np.ndarray, u: np.ndarray, residual: np.ndarray) -> dict[str, Any]:
    """Residual RMS (and mean) by category, relative to its overall RMS.

    Categories: ascending / descending / holding; near reversals (within 2 % of the
    record's reversals' spacing) vs elsewhere; extremes (outer 10 % of the input
    range); slow / medium / fast rate terciles; the first 2 s after a hold begins;
    the slow trend (1 s moving average) and the dominant residual frequency.
    """
    dt = float(t[1] - t[0])
    udot = np.gradient(u, dt)
    overall = _rms(residual)
    speed = np.abs(udot)
    moving = speed > 1e-3 * (np.max(speed) + 1e-300)
    ascending = moving & (udot > 0)
    descending = moving & (udot < 0)
    holding = ~moving
    flips = np.flatnonzero(np.diff(np.sign(udot[moving])) != 0)
    reversal_index = np.flatnonzero(moving)[flips] if flips.size else np.array([], int)
    near = np.zeros(u.size, bool)
    window = max(1, int(0.05 / dt))
    for i in reversal_index:
        near[max(0, i - window) : i + window + 1] = True
    lo, hi = np.min(u), np.max(u)
    extreme = (u < lo + 0.1 * (hi - lo)) | (u > hi - 0.1 * (hi - lo))
    terciles = np.quantile(speed[moving], [1 / 3, 2 / 3]) if moving.any() else [0, 0]
    slow = moving & (speed <= terciles[0])
    fast = moving & (speed > terciles[1])
    medium = moving & ~slow & ~fast
    after_hold = np.zeros(u.size, bool)
    hold_starts = np.flatnonzero(np.diff(holding.astype(int)) == 1)
    for i in hold_starts:
        after_hold[i : i + int(2.0 / dt)] = True
    kernel = max(1, int(1.0 / dt))
    trend = np.convolve(residual, np.ones(kernel) / kernel, mode="same")
    spectrum = np.abs(np.fft.rfft(residual - residual.mean())) ** 2
    freqs = np.fft.rfftfreq(residual.size, dt)
    usable = freqs > 2.0 / (t[-1] - t[0])
    peak = float(freqs[usable][np.argmax(spectrum[usable])]) if usable.any() else 0.0

    def category(mask):
        return {
            "rms": _rms(residual[mask]),
            "mean": float(np.mean(residual[mask])) if mask.any() else float("nan"),
            "fraction": float(np.mean(mask)),
            "relative": _rms(residual[mask]) / overall if overall > 0 else float("nan"),
        }

    return {
        "overall_rms": overall,
        "ascending": category(ascending),
        "descending": category(descending),
        "holding": category(holding),
        "near_reversals": category(near),
        "away_from_reversals": category(~near),
        "extremes": category(extreme),
        "slow_rate": category(slow),
        "medium_rate": category(medium),
        "fast_rate": category(fast),
        "after_hold": category(after_hold),
        "slow_trend_rms": _rms(trend),
        "dominant_frequency_hz": peak,
        "effective_samples": effective_samples(residual),
    }


def _standing_out(
    where: dict[str, Any], labels: dict[str, str], trend: str
) -> list[str]:
    """The labelled categories whose residual RMS is `CONCENTRATED` times the
    overall or more, and the slow trend when it carries `CARRIES` of the residual."""
    # Judged on the figures as quoted, so the words never contradict them.
    parts = []
    for key, label in labels.items():
        entry = where[key]
        relative = round(float(entry["relative"]), 2)
        if entry["fraction"] > MIN_FRACTION and relative >= CONCENTRATED:
            parts.append(f"{label} ({relative:.2f}x the overall RMS)")
    overall = where["overall_rms"]
    share = round(where["slow_trend_rms"] / overall, 2) if overall > 0 else 0.0
    if share >= CARRIES:
        parts.append(trend.format(share=share))
    return parts


_EVEN = "spread evenly over the {what} (no part of it stands out)"


def describe(where: dict[str, Any]) -> str:
    """One sentence naming the categories where the residual stands out (and
    nothing else: no category reaching `CONCENTRATED` reads as spread evenly)."""
    labels = {
        "ascending": "on the ascending branch",
        "descending": "on the descending branch",
        "holding": "while the input holds",
        "near_reversals": "near reversals",
        "extremes": "at the extremes of the stroke",
        "slow_rate": "at slow rates",
        "fast_rate": "at fast rates",
        "after_hold": "in the seconds after a hold begins",
    }
    trend = "as a slow trend in time ({share:.0%} of it survives a 1 s average)"
    parts = _standing_out(where, labels, trend) or [_EVEN.format(what="record")]
    frequency = where["dominant_frequency_hz"]
    peak = (
        f"; dominant residual frequency {frequency:.3g} Hz"
        if frequency > 0
        else "; the record is too short for a dominant residual frequency"
    )
    return "mismatch " + "; ".join(parts) + peak


def locate_cycles(
    x: np.ndarray, force: np.ndarray, residual: np.ndarray
) -> dict[str, Any]:
    """Where a quasi-static cyclic test's residual lives, relative to its overall RMS.

    Categories: push (x > 0) / pull (x < 0); loading (|x| growing) / unloading;
    near zero force (|F| < 15 % of its peak, where pinching shows) and reloading
    through it; near the peaks of each excursion (|x| > 70 % of the largest |x| so
    far); the first / last third of the test. Also the residual's part that is even
    in x (the same in push and pull at equal |x|: a symmetric Bouc-Wen force cannot
    produce it), the slow trend (a moving average
    over 1/25 of the record), the dissipated energy in units of max|F| * max|x|
    and, at the peaks of the last third, the mean of residual * sign(F) (negative:
    the model's force is too large there, as when strength degrades).
    """
    overall = _rms(residual)
    n = residual.size
    step = np.diff(x, prepend=x[0])
    loading = x * step > 0
    near_zero = np.abs(force) < 0.15 * np.max(np.abs(force))
    envelope = np.maximum.accumulate(np.abs(x))
    peaks = np.abs(x) > 0.7 * np.maximum(envelope, 1e-300)
    third = np.arange(n) * 3 // n
    kernel = max(1, n // 25)
    trend = np.convolve(residual, np.ones(kernel) / kernel, mode="same")
    energy = float(np.sum(0.5 * (force[1:] + force[:-1]) * np.diff(x)))
    scale = max(float(np.max(np.abs(force)) * np.max(np.abs(x))), 1e-300)
    late_peaks = peaks & (third == 2)
    # A Bouc-Wen force is odd: F(-x history) = -F(x history). What push and pull do
    # not share is the residual's even part: bin it by |x| (and loading or not) and
    # average the two sides' means.
    levels = np.searchsorted(
        np.quantile(np.abs(x), np.linspace(0, 1, 11)[1:-1]), np.abs(x)
    ) * 2 + loading.astype(int)
    even = np.zeros_like(residual)
    for label in np.unique(levels):
        push_bin, pull_bin = (levels == label) & (x > 0), (levels == label) & (x < 0)
        if push_bin.any() and pull_bin.any():
            middle = 0.5 * (residual[push_bin].mean() + residual[pull_bin].mean())
            even[push_bin | pull_bin] = middle

    def category(mask):
        return {
            "rms": _rms(residual[mask]),
            "mean": float(np.mean(residual[mask])) if mask.any() else float("nan"),
            "fraction": float(np.mean(mask)),
            "relative": _rms(residual[mask]) / overall if overall > 0 else float("nan"),
        }

    return {
        "overall_rms": overall,
        "push": category(x > 0),
        "pull": category(x < 0),
        "loading": category(loading),
        "unloading": category(~loading),
        "near_zero_force": category(near_zero),
        "reloading_near_zero_force": category(near_zero & ~loading),
        "peaks": category(peaks),
        "first_third": category(third == 0),
        "last_third": category(third == 2),
        "late_peak_force_excess": (
            float(np.mean((residual * np.sign(force))[late_peaks]))
            if late_peaks.any()
            else float("nan")
        ),
        "even_part_rms": _rms(even),
        "slow_trend_rms": _rms(trend),
        "dissipated_energy": energy / scale,
        "effective_samples": effective_samples(residual),
    }


def describe_cycles(where: dict[str, Any]) -> str:
    """One sentence naming the parts of a cyclic test where the residual stands
    out."""
    labels = {
        "push": "in push (x > 0)",
        "pull": "in pull (x < 0)",
        "near_zero_force": "near zero force",
        "reloading_near_zero_force": "on reloading through zero force",
        "peaks": "at the peaks of the excursions",
        "first_third": "in the first third of the test",
        "last_third": "in the last third of the test",
    }
    trend = (
        "as a slow trend along the test ({share:.0%} of it survives a moving "
        "average over 1/25 of the record)"
    )
    parts = _standing_out(where, labels, trend) or [_EVEN.format(what="test")]
    return "mismatch " + "; ".join(parts)
