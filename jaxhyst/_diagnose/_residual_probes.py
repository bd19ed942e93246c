"""Model-free predictors of a residual, for the unexplained-structure check: samples
in the same bin of what the recording shows (the input's level and direction; a
damper's velocity and command, and how far its command stands from its recent past)
share one value, learnt on the fitted samples."""

import equinox as eqx
import numpy as np

from .._recording import Recording


class ResidualProbe(eqx.Module):
    """Bins of what a structured residual may be a function of.

    - `labels`: each sample's bin (non-negative integers);
    - `what`: the bins' variables in words ("the velocity and the command");
    - `resembles`: what a structure this probe finds looks like, in words.
    """

    labels: np.ndarray
    what: str
    resembles: str


def quantile_bins(values: np.ndarray, bins: int) -> np.ndarray:
    """Each value's bin among `bins` of equal counts."""
    edges = np.quantile(values, np.linspace(0, 1, bins + 1)[1:-1])
    return np.searchsorted(edges, values)


def loop_labels(x: np.ndarray, bins: int = 16) -> np.ndarray:
    """Bins over the input's level and its direction of motion: a residual that is
    a function of them is loop-shaped (it repeats cycle after cycle)."""
    rising = np.diff(x, prepend=x[0]) >= 0
    return quantile_bins(x, bins) * 2 + rising.astype(int)


def velocity_command_probe(
    recording: Recording, *, velocity_bins: int = 12, command_bins: int = 4
) -> ResidualProbe:
    """Bins over the velocity (by quantile, so both directions and the reversals
    are resolved) and the command's level: a damper's force is mostly a function
    of the two, so a residual that is one is force-velocity physics the model's
    form lacks."""
    x = np.asarray(recording.u)
    velocity = np.gradient(x, np.asarray(recording.t))
    command = np.asarray(recording.more_inputs[0])
    levels = np.unique(command)
    by_command = (
        np.searchsorted(levels, command)
        if levels.size <= command_bins
        else quantile_bins(command, command_bins)
    )
    return ResidualProbe(
        quantile_bins(velocity, velocity_bins) * command_bins + by_command,
        "the velocity and the command",
        "a force-velocity mismatch (it follows the velocity and the command, "
        "whatever the displacement): a field dependence, roll-off or valving whose "
        "form the catalogue's does not match, or a base fit left in a wrong basin",
    )


def command_history_probe(
    recording: Recording, *, memory: float = 0.02, bins: int = 8
) -> ResidualProbe:
    """Bins over how far the command stands from its own recent past (its
    exponential average over `memory` seconds: a field still settling after a
    change), its level, and the direction of motion: a residual that is a function
    of them is a transient after command changes. `memory` is a driver's time
    constant (published MR damper drivers settle in 5 to 30 ms)."""
    from scipy.signal import lfilter  # deferred: scipy.signal costs import time

    command = np.asarray(recording.more_inputs[0])
    decay = float(np.exp(-recording.dt / memory))
    recent = lfilter([1 - decay], [1.0, -decay], command, zi=[decay * command[0]])[0]
    moving = np.gradient(np.asarray(recording.u)) >= 0
    return ResidualProbe(
        (quantile_bins(command - recent, bins) * 2 + quantile_bins(command, 2)) * 2
        + moving.astype(int),
        "how far the command stands from its recent past and the direction of motion",
        "a transient after the command changes that the catalogue's first-order "
        "driver lag does not follow (a driver of higher order or with a rate "
        "limit, eddy currents in the coil's core)",
    )
