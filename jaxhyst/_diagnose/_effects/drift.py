"""Drift: an output offset or slow wander that does not follow the input."""

import math
from typing import ClassVar

from .._locate import MIN_FRACTION
from .base import (
    AbstractEffect,
    Figure,
    carries,
    conclude,
    fitted,
    named_units,
)


# A drift term is named only when it exceeds this many standard errors.
SETTLED = 2.0


# The residual while the input holds is a constant offset when its mean carries
# at least this share of its RMS.
CONSTANT = 0.9


def _at_rest(where) -> Figure:
    """Whether the residual while the input holds is a near-constant offset (time
    records only: `locate`'s "holding" category)."""
    holding = where.get("holding")
    if holding is None or not holding["fraction"] > MIN_FRACTION:
        return Figure(False, "")
    mean, rms = float(holding["mean"]), float(holding["rms"])
    if not (math.isfinite(mean) and rms > 0):
        return Figure(False, "")
    if round(abs(mean) / rms, 2) >= CONSTANT:
        return Figure(
            True,
            f"while the input holds ({holding['fraction']:.0%} of the record) the "
            f"residual is a near-constant {mean:.3g} (its RMS {rms:.3g}): an offset "
            "of the output at rest, such as a sensor zero, not hysteresis",
        )
    return Figure(False, "")


class Drift(AbstractEffect):
    """Legendre terms in time (offset, trend, curvature, wander) added to the
    output: sensor offsets, thermal drift, load-cell zero shifts."""

    name: ClassVar[str] = "drift"
    # Its forms (polynomials, a spline) are all slow functions of time.
    form_in_loops: ClassVar[bool] = False
    parameters: ClassVar[tuple[str, ...]] = ("offset", "trend", "curvature", "wander")
    additive: ClassVar[tuple[str, ...]] = parameters
    forms: ClassVar[dict[str, tuple[str, ...]]] = {"legendre": parameters}
    meaning: ClassVar[str] = (
        "the output has an offset or slow wander that does not follow the input "
        "(sensor offset, thermal drift)"
    )

    def evidence(self, where, model):
        trend = carries(
            where["slow_trend_rms"],
            where["overall_rms"],
            "a slow trend (the residual's moving average)",
        )
        return conclude([_at_rest(where), trend])

    def units(self, *, time, input, output):
        # Each term is an output times a Legendre polynomial of the time in [-1, 1].
        return dict.fromkeys(self.parameters, named_units(time, input, output).output)

    def reading(self, values, errors, units):
        # offset + trend*s + curvature*(s^2 - 1/3) + wander*(5 s^3 - 3 s)/2, s from
        # -1 to 1: the trend moves the output 2*trend from start to end, the ends
        # sit `curvature` above the middle, and the wander reaches +-wander at the
        # ends with opposite bumps inside (an S). Terms within `SETTLED` standard
        # errors of zero are named as such: an offset alone reads as an offset.
        def q(name, scale=1.0):
            return fitted(values, errors, units, name, scale)

        def resolved(name):
            error = errors.get(name, math.nan)
            return math.isfinite(error) and abs(values[name]) > SETTLED * error

        rises = values["trend"] >= 0
        bends = values["curvature"] >= 0
        shapes = {
            "trend": f"a linear trend {'raises' if rises else 'lowers'} it by "
            f"{q('trend', 2.0 if rises else -2.0)} from the start of the record to "
            "its end",
            "curvature": f"curvature puts its ends {q('curvature', 1.0 if bends else -1.0)} "
            f"{'above' if bends else 'below'} its middle",
            "wander": f"an S-shaped wander reaches {q('wander')} at the end (its "
            "opposite at the start)",
        }
        shown = [text for name, text in shapes.items() if resolved(name)]
        hidden = [name for name in shapes if not resolved(name)]
        if not shown:
            return (
                f"a constant offset of the output, {q('offset')} (a sensor zero): its "
                f"{', '.join(hidden)} are within {SETTLED:g} standard errors of zero"
            )
        text = f"the output is offset by {q('offset')} on average; " + "; ".join(shown)
        if hidden:
            text += (
                f"; its {', '.join(hidden)} are within {SETTLED:g} standard errors of "
                "zero"
            )
        return text
