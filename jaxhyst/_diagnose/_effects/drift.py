"""Drift: an output offset or slow wander that does not follow the input."""

from typing import ClassVar

from .base import AbstractEffect


class Drift(AbstractEffect):
    """Legendre terms in time (offset, trend, curvature, wander) added to the
    output: sensor offsets, thermal drift, load-cell zero shifts."""

    name: ClassVar[str] = "drift"
    parameters: ClassVar[tuple[str, ...]] = ("offset", "trend", "curvature", "wander")
    meaning: ClassVar[str] = (
        "the output has an offset or slow wander that does not follow the input "
        "(sensor offset, thermal drift)"
    )

    def evidence(self, where, model):
        share = where["slow_trend_rms"] / max(where["overall_rms"], 1e-300)
        return f"a slow trend carries {share:.0%} of the residual"
