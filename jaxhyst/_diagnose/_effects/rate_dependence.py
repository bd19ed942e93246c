"""Rate dependence: the loop changes with how fast the input moves."""

import math
from typing import ClassVar

from ..._models.extended import ExtendedPiezo
from .base import (
    AbstractEffect,
    RefitScales,
    concentration,
    conclude,
    contrast,
    fitted,
    model_as,
    named_units,
    time_scale,
)
from .creep import FASTEST_CREEP


class RateDependence(AbstractEffect):
    """`ExtendedPiezo`'s rate_gain, rate_amplitude (the loop widens or saturates
    with the rate) and a Kelvin-Voigt element (viscous, viscous_time)."""

    name: ClassVar[str] = "rate_dependence"
    parameters: ClassVar[tuple[str, ...]] = (
        "rate_gain",
        "viscous",
        "rate_amplitude",
        "viscous_time",
    )
    meaning: ClassVar[str] = (
        "the loop changes with how fast the input moves (it widens, opens or "
        "rotates at higher rates)"
    )
    log_scaled: ClassVar[tuple[str, ...]] = ("viscous_time",)
    shape_parameters: ClassVar[tuple[str, ...]] = ("viscous_time",)
    forms: ClassVar[dict[str, tuple[str, ...]]] = {
        "rate_scaled_loop": ("rate_gain", "rate_amplitude"),
        "kelvin_voigt": ("viscous", "viscous_time"),
    }

    def bounds(self, name, value, scales: RefitScales):
        if name == "viscous_time":
            # A Kelvin-Voigt element and one relaxation mode of creep are the same
            # equation (a first-order lag of the drive added to the output), so
            # the catalogue draws the line where creep's modes begin: a viscous
            # element relaxes faster than creep's fastest mode, within a cycle of
            # the drive; a slower relaxation is creep's.
            # (`ExtendedPiezo.parameter_ceilings` holds the line in polishes.)
            return (min(4.0 / scales.sample_rate, FASTEST_CREEP / 2), FASTEST_CREEP)
        return None

    def starting_points(self, current, step, scales):
        models = super().starting_points(current, step, scales)
        if step.get("viscous"):
            # A viscoelastic element saturates above 1/time: longer times need
            # more gain.
            piezo = model_as(current, ExtendedPiezo, self.name)
            viscous = float(piezo.viscous) + step["viscous"]
            models += [
                current.replace(viscous=gain * viscous, viscous_time=time)
                for time in (0.005, 0.01, 0.02, FASTEST_CREEP)
                for gain in (1.0, 2.0, 4.0)
            ]
        return models

    def evidence(self, where, model):
        return conclude(
            [
                concentration(where, "fast_rate", "at fast rates"),
                concentration(where, "slow_rate", "at slow rates"),
                contrast(
                    where,
                    "fast_rate",
                    "slow_rate",
                    "its RMS at fast rates is {ratio:.2f}x that at slow rates",
                ),
                contrast(
                    where,
                    "slow_rate",
                    "fast_rate",
                    "its RMS at slow rates is {ratio:.2f}x that at fast rates",
                ),
            ]
        )

    def units(self, *, time, input, output):
        # Rates enter relative to the record's RMS drive rate (rate_scale), so the
        # gains are pure numbers; viscous*(u - z)/(viscous_time*rate_scale) is an
        # output.
        u = named_units(time, input, output)
        return {
            "rate_gain": "1",
            "viscous": u.output,
            "rate_amplitude": "1",
            "viscous_time": u.time,
        }

    def reading(self, values, errors, units):
        def percent(name, factor=1.0):
            return fitted(values, errors, units, name, 100 * factor, "%")

        # At the record's RMS drive rate |udot|/rate_scale = 1: hdot is scaled by
        # 1 + rate_gain and A1 by 1 + rate_amplitude*log(2).
        words = (
            "at the record's RMS drive rate the hysteretic rate changes by "
            f"{percent('rate_gain')} (rate_gain, linear in the rate) and its gain "
            f"A1 by {percent('rate_amplitude', math.log(2))} (rate_amplitude, "
            "logarithmic in the rate)"
        )
        if values["viscous"] == 0:
            return f"{words}; no viscous term (viscous = 0, so viscous_time is inert)"
        scale, unit = time_scale(values["viscous_time"], units["viscous_time"])
        return (
            f"{words}; a viscous term adds viscous*udot/(RMS rate) to the output, "
            f"{fitted(values, errors, units, 'viscous')} at that rate, saturating "
            "for changes faster than "
            f"viscous_time = {fitted(values, errors, units, 'viscous_time', scale, unit)}"
        )
