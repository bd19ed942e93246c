"""Loading protocols of structural tests: imposed-displacement histories.

Loading protocols (`loading_protocol`) imitate real tests: "cyclic", stepwise growing
amplitudes with 2-3 cycles per level (ATC-24 / FEMA 461), and "earthquake", the
turning points of an enveloped random-phase band-limited displacement (a
quasi-static earthquake-like history). Each excursion is sampled as a test controller
does, with nearly uniform displacement increments, turning points exactly on samples.
There is no real time: the record's time is the pseudo time t = sample index (dt = 1,
`time_unit` "sample"); the models are rate independent, so only the order matters.
"""

import math

import jax.numpy as jnp
import numpy as np
from jaxtyping import PRNGKeyArray

from .._inputs import InputPath
from ._random import _rng


PROTOCOLS: tuple[str, ...] = ("cyclic", "earthquake")
_POINTS = (500, 20000)  # the accepted range of `points`


def _check_points(owner: str, points) -> None:
    if isinstance(points, bool) or not isinstance(points, (int, np.integer)):
        raise TypeError(
            f"{owner}: points must be an integer number of samples, e.g. points=2000, "
            f"got {points!r}."
        )
    if not _POINTS[0] <= points <= _POINTS[1]:
        raise ValueError(
            f"{owner}(points={points}): points must be between {_POINTS[0]} and "
            f"{_POINTS[1]}; real cyclic tests have 1000-4000."
        )


def _check_protocol(owner: str, protocol) -> str:
    if protocol == "earthquake-like":
        protocol = "earthquake"
    if protocol not in PROTOCOLS:
        raise ValueError(
            f"{owner}(protocol={protocol!r}): protocol must be one of "
            f"{', '.join(PROTOCOLS)}."
        )
    return protocol


def _sample_excursions(vertices: np.ndarray, points: int) -> np.ndarray:
    """`points` samples along the piecewise-linear path through `vertices` (its
    turning points): every excursion gets a whole number of equal steps, in
    proportion to its length (at least one), so the increments are nearly uniform
    and every turning point is a sample."""
    vertices = np.asarray(vertices, dtype=float)
    keep = np.concatenate([[True], np.abs(np.diff(vertices)) > 0])
    vertices = vertices[keep]
    lengths = np.abs(np.diff(vertices))
    steps = points - 1
    if lengths.size > steps:
        raise ValueError(
            f"the protocol has {lengths.size} excursions but only {steps} steps; "
            "ask for more points."
        )
    raw = lengths / lengths.sum() * steps
    counts = np.maximum(np.floor(raw).astype(int), 1)
    while counts.sum() < steps:  # largest remainders first
        counts[np.argmax(raw - counts)] += 1
    while counts.sum() > steps:  # the minimum of one step overshot: take from the
        counts[np.argmax(np.where(counts > 1, counts - raw, -np.inf))] -= 1  # longest
    pieces = [vertices[:1]]
    for start, end, count in zip(vertices[:-1], vertices[1:], counts):
        pieces.append(np.linspace(start, end, count + 1)[1:])
    return np.concatenate(pieces)


def _cyclic_vertices(rng: np.random.Generator, x_y: float) -> tuple[np.ndarray, str]:
    levels = int(rng.integers(6, 11))
    cycles = int(rng.choice([2, 3]))
    first, last = rng.uniform(0.2, 0.5), rng.uniform(4.0, 8.0)
    amplitudes = x_y * np.geomspace(first, last, levels)
    sign = float(rng.choice([1.0, -1.0]))
    vertices = [0.0]
    for a in amplitudes:
        vertices += [sign * a, -sign * a] * cycles
    vertices.append(0.0)
    growth = (last / first) ** (1 / (levels - 1))
    what = (
        f"cyclic, {levels} levels x {cycles} cycles from {first:.3g} to {last:.3g} x_y "
        f"(x {growth:.3g} per level), {'push' if sign > 0 else 'pull'} first"
    )
    return np.asarray(vertices), what


def _earthquake_vertices(
    rng: np.random.Generator, x_y: float
) -> tuple[np.ndarray, str]:
    dense = 4096
    tau = np.linspace(0.0, 1.0, dense)
    low = rng.uniform(8.0, 15.0)  # cycles per record
    high = low * rng.uniform(3.0, 5.0)
    components = 40
    f = rng.uniform(low, high, components)
    amplitude = 1.0 / f  # a displacement spectrum falling with frequency
    phase = rng.uniform(0.0, 2 * math.pi, components)
    signal = np.sum(
        amplitude[:, None] * np.sin(2 * math.pi * f[:, None] * tau + phase[:, None]),
        axis=0,
    )
    rise = rng.uniform(0.08, 0.2)
    plateau_end = rise + rng.uniform(0.25, 0.45)
    decay = -math.log(0.03) / (1 - plateau_end)
    envelope = np.where(
        tau < rise,
        (tau / rise) ** 2,
        np.where(tau < plateau_end, 1.0, np.exp(-decay * (tau - plateau_end))),
    )
    x = signal * envelope
    peak = rng.uniform(3.0, 6.0)
    x *= peak * x_y / np.max(np.abs(x))
    slope = np.diff(x)
    turns = np.flatnonzero(np.sign(slope[1:]) != np.sign(slope[:-1])) + 1
    vertices = np.concatenate([[0.0], x[turns], [0.0]])
    what = (
        f"earthquake-like, {components} random-phase components at {low:.3g}-"
        f"{high:.3g} cycles per record, envelope rise {rise:.2f}, strong motion to "
        f"{plateau_end:.2f}, peak {peak:.3g} x_y, {vertices.size - 1} excursions"
    )
    return vertices, what


def loading_protocol(
    key: PRNGKeyArray,
    *,
    yield_displacement: float,
    protocol: str = "cyclic",
    points: int = 2000,
) -> tuple[InputPath, str]:
    """An imposed-displacement history like a real quasi-static test, and a one-line
    description of it. The path's time is the pseudo time t = sample index (t0 = 0,
    dt = 1).

    - "cyclic": 6-10 stepwise growing amplitude levels (x 1.3-1.9 per level, from
      0.2-0.5 to 4-8 times `yield_displacement`) with 2 or 3 full cycles each, push
      or pull first, ending at zero (ATC-24 / FEMA 461 protocols);
    - "earthquake": the turning points of an enveloped random-phase band-limited
      displacement (40 components over a 3-5 x band of 8-75 cycles per record,
      amplitudes ~1/f; quadratic rise, strong-motion plateau, exponential decay),
      peaking at 3-6 times `yield_displacement`, ending at zero.

    Each excursion between turning points is sampled with equal steps, the steps of
    all excursions as nearly equal as whole numbers allow, as a test controller does.
    """
    owner = "loading_protocol"
    rng = _rng(key, owner)
    _check_points(owner, points)
    protocol = _check_protocol(owner, protocol)
    if not (
        isinstance(yield_displacement, (int, float, np.number))
        and yield_displacement > 0
        and math.isfinite(yield_displacement)
    ):
        raise ValueError(
            f"{owner}(yield_displacement={yield_displacement!r}): pass the yield "
            "displacement, a positive number (mm)."
        )
    build = _cyclic_vertices if protocol == "cyclic" else _earthquake_vertices
    vertices, what = build(rng, float(yield_displacement))
    x = _sample_excursions(vertices, points)
    return InputPath(0.0, 1.0, jnp.asarray(x)), what
