"""Tests a user could run next: inputs that may separate effects a record cannot
tell apart. The diagnosis simulates the rival fitted models under each and reports
how far apart their outputs would be, in noise sigmas.

Every probe has the analysed record's sample count and step, so simulating it reuses
the programs the diagnosis already compiled.
"""

import math

import equinox as eqx
import numpy as np

from .._inputs import InputPath
from .._recording import Recording


class Probe(eqx.Module):
    """A proposed test: its input in words, and as a path to simulate."""

    description: str
    path: InputPath


def _path(recording: Recording, values: np.ndarray) -> InputPath:
    return InputPath(float(recording.t[0]), recording.dt, values)


def dominant_frequency(recording: Recording) -> float:
    """The input's strongest frequency (cycles per time unit), at least two per
    record."""
    u = recording.u - recording.u.mean()
    spectrum = np.abs(np.fft.rfft(u)) ** 2
    freqs = np.fft.rfftfreq(u.size, recording.dt)
    usable = freqs >= 2.0 / recording.duration
    if not usable.any() or spectrum[usable].max() <= 0:
        return 2.0 / recording.duration
    return float(freqs[usable][np.argmax(spectrum[usable])])


def _sine(t: np.ndarray, frequency: float, low: float, high: float) -> np.ndarray:
    """A sine from `low` up to `high` and back, starting at `low`."""
    return low + 0.5 * (high - low) * (1 - np.cos(2 * math.pi * frequency * t))


def _triangle(t: np.ndarray, frequency: float, low: float, high: float) -> np.ndarray:
    phase = (frequency * t) % 1.0
    return low + (high - low) * (1 - np.abs(1 - 2 * phase))


def _staircase(t: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """Hold each of `levels` for an equal share of `t`, with raised-cosine ramps
    of a tenth of a hold between them."""
    share = (t - t[0]) / (t[-1] - t[0] + 1e-300) * levels.size
    index = np.minimum(np.floor(share).astype(int), levels.size - 1)
    within = share - index
    previous = np.concatenate([[levels[0]], levels[:-1]])[index]
    ramp = np.clip(within / 0.1, 0.0, 1.0)
    blend = 0.5 * (1 - np.cos(math.pi * ramp))
    return previous + (levels[index] - previous) * blend


def piezo_probes(recording: Recording) -> list[Probe]:
    """Inputs over the record's range and duration: sines ten times faster and
    slower than its dominant frequency, the same sine at half amplitude, a
    triangle (constant rates), and a staircase with holds."""
    t = recording.t - recording.t[0]
    low, high = float(recording.u.min()), float(recording.u.max())
    mid, unit = 0.5 * (low + high), recording.time_unit or "time unit"
    f0 = dominant_frequency(recording)
    fast = min(10 * f0, 0.05 / recording.dt)
    slow = max(f0 / 10, 2.0 / recording.duration)
    levels = np.array([0.25, 0.5, 0.75, 1.0, 0.75, 0.5, 0.25, 0.0])
    hold = recording.duration / levels.size
    rate = "Hz" if unit == "s" else f"cycles per {unit}"
    span = f"over the same range ({low:.3g} to {high:.3g} {recording.input_unit})"
    return [
        Probe(
            f"a sine at {fast:.3g} {rate} {span}",
            _path(recording, _sine(t, fast, low, high)),
        ),
        Probe(
            f"a sine at {slow:.3g} {rate} {span}",
            _path(recording, _sine(t, slow, low, high)),
        ),
        Probe(
            f"a sine at {f0:.3g} {rate} at half the amplitude, around the same mean",
            _path(recording, _sine(t, f0, 0.5 * (low + mid), 0.5 * (mid + high))),
        ),
        Probe(
            f"a triangle at {f0:.3g} {rate} {span} (constant rates)",
            _path(recording, _triangle(t, f0, low, high)),
        ),
        Probe(
            f"a staircase up and down the same range with holds of {hold:.3g} {unit}",
            _path(recording, _staircase(t, low + (high - low) * levels)),
        ),
    ]


def _cycles(n: int, peaks: np.ndarray) -> np.ndarray:
    """Piecewise-linear displacement through 0 -> peaks[0] -> 0 -> peaks[1] ...,
    over `n` samples."""
    knots = np.zeros(2 * peaks.size + 1)
    knots[1::2] = peaks
    at = np.round(np.linspace(0, n - 1, knots.size))  # every knot on a sample
    return np.interp(np.arange(n), at, knots)


def cyclic_probes(recording: Recording) -> list[Probe]:
    """Displacement histories with the record's sample count: repeated cycles at
    the largest amplitude, cycles growing beyond it, one-sided cycles, and small
    cycles between large ones."""
    n, reach = recording.num_samples, float(np.max(np.abs(recording.u)))
    unit = f" {recording.input_unit}" if recording.input_unit else ""
    repeated = np.tile([reach, -reach], 10)
    growing = np.repeat(np.linspace(0.25, 1.5, 6) * reach, 2) * np.tile([1, -1], 6)
    one_sided = np.concatenate([np.full(5, reach), np.full(5, -reach)])
    small = np.tile([reach, 0.25 * reach, -0.25 * reach, -reach], 4)
    return [
        Probe(
            f"ten full cycles at the largest amplitude ({reach:.3g}{unit})",
            _path(recording, _cycles(n, repeated)),
        ),
        Probe(
            f"cycles growing from 25 % to 150 % of the largest amplitude ({reach:.3g}{unit})",
            _path(recording, _cycles(n, growing)),
        ),
        Probe(
            "five cycles in push only, then five in pull only, at the largest amplitude",
            _path(recording, _cycles(n, one_sided)),
        ),
        Probe(
            "small cycles (25 % of the largest amplitude) between full ones",
            _path(recording, _cycles(n, small)),
        ),
    ]
