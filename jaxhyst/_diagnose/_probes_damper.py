"""Tests an MR damper's user could run next: displacement sines at constant
commands, with a switching command, and slowly (near-reversal behaviour), each with
the analysed record's sample count and step."""

import math

import numpy as np

from .._inputs import InputPath
from .._recording import Recording
from ._probes import Probe, dominant_frequency


def _path(recording: Recording, x: np.ndarray, command: np.ndarray) -> InputPath:
    return InputPath(float(recording.t[0]), recording.dt, x, channels=command[None])


def damper_probes(recording: Recording) -> list[Probe]:
    """Sines of the displacement at the record's dominant frequency and half its
    stroke around its mean, at the lowest, middle and highest command of the record;
    the same sine while the command steps between its lowest and highest every
    quarter period (so each level meets every phase of the motion); and a sine ten
    times slower at the highest command (low velocities: the pre-yield region and
    any roll-off)."""
    t = recording.t - recording.t[0]
    x = recording.u
    command = recording.more_inputs[0]
    centre, reach = float(np.mean(x)), 0.5 * float(np.ptp(x))
    low, high = float(np.min(command)), float(np.max(command))
    middle = 0.5 * (low + high)
    f0 = dominant_frequency(recording)
    slow = max(f0 / 10, 2.0 / recording.duration)
    unit = recording.time_unit or "time unit"
    rate = "Hz" if unit == "s" else f"cycles per {unit}"
    volts = recording.more_input_units[0] if recording.more_input_units else ""
    sine = centre + reach * np.sin(2 * math.pi * f0 * t)
    slow_sine = centre + reach * np.sin(2 * math.pi * slow * t)
    quarter = np.floor(4 * f0 * t).astype(int) % 2 == 1
    stepping = np.where(quarter, high, low)
    motion = (
        f"a displacement sine at {f0:.3g} {rate}, {reach:.3g} {recording.input_unit}"
    )

    def at(level: float) -> np.ndarray:
        return np.full(t.shape, level)

    def named(level: float) -> str:
        return f"{level:.3g} {volts}".rstrip()

    return [
        Probe(
            f"{motion}, at a constant command {named(low)}",
            _path(recording, sine, at(low)),
        ),
        Probe(
            f"{motion}, at a constant command {named(middle)}",
            _path(recording, sine, at(middle)),
        ),
        Probe(
            f"{motion}, at a constant command {named(high)}",
            _path(recording, sine, at(high)),
        ),
        Probe(
            f"{motion}, with the command stepping between {named(low)} and "
            f"{named(high)} every quarter period",
            _path(recording, sine, stepping),
        ),
        Probe(
            f"a displacement sine at {slow:.3g} {rate} (slow), {reach:.3g} "
            f"{recording.input_unit}, at a constant command {named(high)}",
            _path(recording, slow_sine, at(high)),
        ),
    ]
