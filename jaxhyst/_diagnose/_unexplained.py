"""What the catalogue does not explain: structure left in the final residual that
a model-free probe, fitted on the fitted samples, predicts on the held-out ones."""

import math

import numpy as np

from .._recording import Recording
from ._families import AbstractFamily
from ._policy import AdoptionPolicy
from ._residual_probes import bin_prediction, loop_labels
from ._results import Unexplained
from ._score import NoiseModel


def _time_labels(n: int, bins: int = 12) -> np.ndarray:
    return np.minimum(np.arange(n) * bins // n, bins - 1)


def _loop_resemblance(x: np.ndarray, pattern: np.ndarray) -> str:
    rising = np.diff(x, prepend=x[0]) >= 0
    up, down = pattern[rising], pattern[~rising]
    common = 0.5 * (np.mean(up) + np.mean(down)) if up.size and down.size else 0.0
    where = int(np.argmax(np.abs(pattern)))
    direction = "rising" if rising[where] else "falling"
    same = (
        float(
            np.corrcoef(
                np.interp(
                    x[~rising],
                    x[rising][np.argsort(x[rising])],
                    up[np.argsort(x[rising])],
                ),
                down,
            )[0, 1]
        )
        if up.size > 2 and down.size > 2
        else math.nan
    )
    if math.isfinite(same) and same > 0.5:
        shape = (
            "the same on both directions of motion: a static function of the input "
            "that the model's form lacks"
        )
    elif math.isfinite(same) and same < -0.5:
        shape = (
            "opposite on the two directions of motion: the loop's width or shape "
            "differs from what the model can form"
        )
    else:
        shape = "different on the two directions of motion"
    return (
        f"a loop-shaped mismatch (it follows the input's level and direction, cycle "
        f"after cycle), {shape}; largest while the input is {direction} near "
        f"{x[where]:.3g} (mean offset {common:.3g})"
    )


def _probe_gain(labels: np.ndarray, residual: np.ndarray, fit: np.ndarray) -> float:
    """The share of the held-out MSE that the probe's bin means (learnt on the
    fitted samples) remove."""
    hold = ~fit
    before = float(np.mean(residual[hold] ** 2))
    if before <= 0:
        return 0.0
    prediction = bin_prediction(labels, residual, fit)
    return (before - float(np.mean((residual - prediction)[hold] ** 2))) / before


def _noise_draws(noise: NoiseModel, n: int, draws: int, seed: int):
    """`draws` series of `n` samples of the residual's AR noise, one at a time (a
    burn-in first; an AR fit at the edge of stationarity is pulled inside it)."""
    from scipy.signal import lfilter  # deferred: scipy.signal costs import time

    ar = np.asarray(noise.ar, float)
    roots = np.roots(np.concatenate([[1.0], -ar]))
    largest = float(np.max(np.abs(roots), initial=0.0))
    if largest >= 0.999:
        ar = ar * (0.999 / largest) ** np.arange(1, ar.size + 1)
    denominator = np.concatenate([[1.0], -ar])
    burn = 1000
    rng = np.random.default_rng(seed)
    for _ in range(draws):
        shocks = rng.standard_normal(n + burn) * math.sqrt(noise.innovation_var)
        yield np.asarray(lfilter([1.0], denominator, shocks))[burn:]


def unexplained_structure(
    recording: Recording,
    family: AbstractFamily,
    residual: np.ndarray,
    fit_mask: np.ndarray,
    policy: AdoptionPolicy,
    *,
    seed: int,
    draws: int = 200,
    undecided: tuple[str, ...] = (),
) -> list[Unexplained]:
    """Structured mismatch left on held-out data: for each probe (a function of the
    input's level and direction; a slow function of time; the family's own,
    `AbstractFamily.residual_probes`), the bin means of the fitted samples'
    residual predict the held-out residual. It is reported when
    that prediction removes more than the policy's minimum gain of the held-out
    MSE and more than the same probe removes from all but one in two hundred of
    `draws` series of the residual's own AR(2) noise (`NoiseModel`, read from
    the whole residual; `seed` draws them): structure, not noise of the colour the
    residual has, and not one of the catalogue's effects, which the diagnosis has
    already tried. A slow noise and a slow drift look alike to the time probe, so
    a residual whose colour is all slow wander is not reported. `undecided`: the
    catalogue effects the record could not decide on (named in each report: part
    of the structure may be theirs). Of the probes that read the inputs, only the
    one that predicts most is reported (they see the same structure); the slow
    function of time is reported beside it."""
    hold = ~fit_mask
    x = np.asarray(recording.u)
    if float(np.mean(residual[hold] ** 2)) <= 0:
        return []
    own = {f"family{i}": p for i, p in enumerate(family.residual_probes(recording))}
    probes = (
        ("loop", loop_labels(x)),
        ("trend", _time_labels(residual.size)),
        *((kind, p.labels) for kind, p in own.items()),
    )
    gains = {kind: _probe_gain(labels, residual, fit_mask) for kind, labels in probes}
    # Only probes above the floor are compared with the noise draws.
    probes = tuple(p for p in probes if gains[p[0]] > policy.min_heldout_gain)
    # Of those that read the inputs, the one that predicts most.
    reading = [kind for kind, _ in probes if kind != "trend"]
    best = max(reading, key=lambda kind: gains[kind], default=None)
    probes = tuple(p for p in probes if p[0] in ("trend", best))
    if not probes:
        return []
    noise = NoiseModel.estimate(residual)
    null = np.array(
        [
            [_probe_gain(labels, draw, fit_mask) for _, labels in probes]
            for draw in _noise_draws(noise, residual.size, draws, seed)
        ]
    )
    found = []
    for (kind, labels), drawn in zip(probes, null.T, strict=True):
        gain = gains[kind]
        if gain <= float(np.quantile(drawn, 0.995)):
            continue
        prediction = bin_prediction(labels, residual, fit_mask)
        change = float(np.sqrt(np.mean(prediction[hold] ** 2)))
        where = family.describe(family.locate(recording, residual))
        if kind == "loop":
            resembles = _loop_resemblance(x, prediction)
            description = (
                "a structured mismatch no effect of the catalogue removed: a "
                "function of the input's level and direction, learnt on the fitted "
                f"samples, predicts {gain:.0%} of the held-out residual's MSE"
            )
        elif kind in own:
            probe = own[kind]
            resembles = probe.resembles
            description = (
                "a structured mismatch no effect of the catalogue removed: a "
                f"function of {probe.what}, learnt on the fitted samples, predicts "
                f"{gain:.0%} of the held-out residual's MSE"
            )
        else:
            resembles = (
                "a slow change along the record that does not follow the input "
                "(the catalogue's drift did not take it up: it may be faster than "
                "its Legendre terms, or tied to the test's history)"
            )
            description = (
                "a structured mismatch no effect of the catalogue removed: a slow "
                "function of time, learnt on the fitted samples, predicts "
                f"{gain:.0%} of the held-out residual's MSE"
            )
        if undecided:
            description += (
                f"; the record could not decide whether {' or '.join(undecided)} "
                f"{'is' if len(undecided) == 1 else 'are'} present (see the "
                "ambiguities), and part of it may be theirs"
            )
        found.append(Unexplained(description, where, change, gain, resembles))
    return found
