"""Where an MR damper record's residual lives: by command level, by velocity (near
reversals, approaching or leaving them, by direction), after the command switches,
along the record; and how much of it follows the command or is even in velocity."""

from typing import Any

import numpy as np

from ._locate import CARRIES, CONCENTRATED, MIN_FRACTION, _rms, effective_samples


# Samples whose |velocity| is in the record's slowest share are "near reversals":
# the pre-yield region, where a rolling-off force shows.
SLOW_SHARE = 0.15
# A command change larger than this share of its range is a switch.
SWITCH = 0.1


def _category(mask: np.ndarray, residual: np.ndarray, overall: float):
    return {
        "rms": _rms(residual[mask]),
        "mean": float(np.mean(residual[mask])) if mask.any() else float("nan"),
        "fraction": float(np.mean(mask)),
        "relative": _rms(residual[mask]) / overall if overall > 0 else float("nan"),
    }


def _part_rms(residual: np.ndarray, part: np.ndarray, known: np.ndarray) -> float:
    """The RMS of the residual's projection on the columns `part` after removing
    what the columns `known` explain (the base model's own directions)."""
    basis, _ = np.linalg.qr(known)
    scale = np.linalg.norm(part, axis=0)
    part = part / np.where(scale > 0, scale, 1.0)
    part = part - basis @ (basis.T @ part)
    coef, *_ = np.linalg.lstsq(part, residual - basis @ (basis.T @ residual))
    return _rms(part @ coef)


def _even_part(velocity: np.ndarray, residual: np.ndarray, bins: int = 10):
    """The residual's part even in velocity (the same at +v and -v): its mean over
    bins of |v|, averaged over the two directions."""
    edges = np.quantile(np.abs(velocity), np.linspace(0, 1, bins + 1)[1:-1])
    level = np.searchsorted(edges, np.abs(velocity))
    even = np.zeros_like(residual)
    for label in np.unique(level):
        up, down = (level == label) & (velocity > 0), (level == label) & (velocity < 0)
        if up.any() and down.any():
            even[up | down] = 0.5 * (residual[up].mean() + residual[down].mean())
    return even


def locate_damper(
    t: np.ndarray,
    x: np.ndarray,
    command: np.ndarray,
    residual: np.ndarray,
    *,
    switch_window: int,
    time_unit: str = "s",
) -> dict[str, Any]:
    """Residual RMS (and mean) by category, relative to its overall RMS.

    Categories: high / low command (above or below the middle of its range); near
    velocity reversals (the slowest `SLOW_SHARE` of |xdot|), split into approaching
    them (xdot*xddot < 0: decelerating) and leaving them; fast (the fastest third);
    positive / negative velocity; the `switch_window` samples after each command
    switch (a change of more than `SWITCH` of its range; `time_unit` names the
    record's time unit for the words). Also the share of the
    residual that follows the command (its projection on command*xdot and
    command*sign(xdot) beyond xdot, sign(xdot) and a constant: what a field-dependent
    force leaves), its part even in velocity, its slow trend (a moving average over
    1/25 of the record) and its dominant frequency."""
    dt = float(t[1] - t[0])
    overall = _rms(residual)
    velocity = np.gradient(x, dt)
    acceleration = np.gradient(velocity, dt)
    speed = np.abs(velocity)
    slow = speed <= np.quantile(speed, SLOW_SHARE)
    fast = speed > np.quantile(speed, 2 / 3)
    approaching = slow & (velocity * acceleration < 0)
    leaving = slow & (velocity * acceleration > 0)
    low, high = float(np.min(command)), float(np.max(command))
    span = high - low
    strong = command > low + 0.5 * span if span > 0 else np.zeros(x.size, bool)
    after = np.zeros(x.size, bool)
    if span > 0:
        for i in np.flatnonzero(np.abs(np.diff(command)) > SWITCH * span):
            after[i + 1 : i + 1 + switch_window] = True
    direction = np.sign(velocity)
    level = (command - low) / span if span > 0 else np.zeros_like(command)
    known = np.stack([velocity, direction, np.ones_like(x)], axis=1)
    follows = np.stack([level * velocity, level * direction], axis=1)
    command_part = _part_rms(residual, follows, known) if span > 0 else 0.0
    kernel = max(1, residual.size // 25)
    trend = np.convolve(residual, np.ones(kernel) / kernel, mode="same")
    spectrum = np.abs(np.fft.rfft(residual - residual.mean())) ** 2
    freqs = np.fft.rfftfreq(residual.size, dt)
    usable = freqs > 2.0 / (t[-1] - t[0])
    peak = float(freqs[usable][np.argmax(spectrum[usable])]) if usable.any() else 0.0
    return {
        "overall_rms": overall,
        "high_command": _category(strong, residual, overall),
        "low_command": _category(~strong, residual, overall),
        "near_reversals": _category(slow, residual, overall),
        "approaching_reversals": _category(approaching, residual, overall),
        "leaving_reversals": _category(leaving, residual, overall),
        "fast": _category(fast, residual, overall),
        "positive_velocity": _category(velocity > 0, residual, overall),
        "negative_velocity": _category(velocity < 0, residual, overall),
        "after_switch": _category(after, residual, overall),
        "switch_window": switch_window * dt,
        "time_unit": time_unit,
        "command_part_rms": command_part,
        "even_part_rms": _rms(_even_part(velocity, residual)),
        "slow_trend_rms": _rms(trend),
        "dominant_frequency_hz": peak,
        "effective_samples": effective_samples(residual),
    }


def describe_damper(where: dict[str, Any]) -> str:
    """One sentence naming where the residual stands out (`CONCENTRATED` times the
    overall RMS or more) and the parts that carry `CARRIES` of it."""
    window, unit = float(where["switch_window"]), str(where["time_unit"])
    if unit == "s":
        window, unit = 1e3 * window, "ms"
    labels = {
        "high_command": "at high command",
        "low_command": "at low command",
        "near_reversals": "near velocity reversals",
        "approaching_reversals": "while decelerating into a reversal",
        "leaving_reversals": "while accelerating out of a reversal",
        "fast": "at high velocity",
        "positive_velocity": "at positive velocity",
        "negative_velocity": "at negative velocity",
        "after_switch": f"in the {window:.3g} {unit} after the command switches",
    }
    parts = []
    for key, label in labels.items():
        entry = where[key]
        relative = round(float(entry["relative"]), 2)
        if entry["fraction"] > MIN_FRACTION and relative >= CONCENTRATED:
            parts.append(f"{label} ({relative:.2f}x the overall RMS)")
    overall = where["overall_rms"]
    for key, label in (
        ("command_part_rms", "the part that follows the command"),
        ("even_part_rms", "the part even in velocity"),
        ("slow_trend_rms", "a slow trend along the record"),
    ):
        share = round(where[key] / overall, 2) if overall > 0 else 0.0
        if share >= CARRIES:
            parts.append(f"{label} carries {share:.0%} of it")
    if not parts:
        parts = ["spread evenly over the record (no part of it stands out)"]
    frequency = where["dominant_frequency_hz"]
    peak = (
        f"; dominant residual frequency {frequency:.3g} Hz"
        if frequency > 0
        else "; the record is too short for a dominant residual frequency"
    )
    return "mismatch " + "; ".join(parts) + peak
