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


def bin_prediction(labels: np.ndarray, residual: np.ndarray, fit: np.ndarray):
    """Each sample's prediction of `residual`: the mean of the fitted samples'
    (`fit`) residual in its bin of `labels` (0 where a bin has no fitted samples)."""
    count = np.bincount(labels[fit], minlength=labels.max() + 1)
    total = np.bincount(labels[fit], weights=residual[fit], minlength=labels.max() + 1)
    means = np.where(count > 0, total / np.maximum(count, 1), 0.0)
    return means[labels]


def loop_probe(recording: Recording) -> ResidualProbe:
    """`loop_labels` of the recording's input, as a probe."""
    return ResidualProbe(
        loop_labels(np.asarray(recording.u)),
        "the input's level and direction of motion",
        "a loop-shaped mismatch (it follows the input's level and direction, cycle "
        "after cycle)",
    )


def excursion_probe(
    recording: Recording, *, position_bins: int = 8, excursion_bins: int = 4
) -> ResidualProbe:
    """Bins over where a cyclic test stands in its loop: the displacement as a
    share of the largest excursion so far (uniform bins over [-1, 1]), the
    direction of motion, and that largest excursion (by quantile). A cyclic test's
    loop changes shape as its excursions grow (cracks open, slips lengthen), so a
    residual that is a function of these is the loop's shape differing from the
    model's, level by level, whatever law its change follows."""
    x = np.asarray(recording.u)
    reach = np.maximum.accumulate(np.abs(x))
    peak = float(reach[-1]) if reach.size else 0.0
    reach = np.maximum(reach, 1e-12 * max(peak, 1e-300))
    position = np.clip(
        ((x / reach + 1) / 2 * position_bins).astype(int), 0, position_bins - 1
    )
    rising = np.diff(x, prepend=x[0]) >= 0
    level = quantile_bins(reach, excursion_bins)
    return ResidualProbe(
        (level * position_bins + position) * 2 + rising.astype(int),
        "where the test stands in its loop (the displacement as a share of the "
        "largest excursion so far, the direction of motion) and that excursion",
        "a loop whose shape differs from the model's level by level (a pinching "
        "or a degradation that follows another law than the catalogue's)",
    )


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
