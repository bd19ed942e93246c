"""Rate dependence: the loop changes with how fast the input moves."""

from typing import ClassVar

from ..._models.extended import ExtendedPiezo
from .base import AbstractEffect, RefitScales, model_as


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

    def bounds(self, name, value, scales: RefitScales):
        if name == "viscous_time":
            return (4.0 / scales.sample_rate, 2.0)
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
                for time in (0.005, 0.01, 0.02, 0.05, 0.1)
                for gain in (1.0, 2.0, 4.0)
            ]
        return models

    def evidence(self, where, model):
        return (
            f"residual RMS at fast rates is {where['fast_rate']['relative']:.2f}x and at "
            f"slow rates {where['slow_rate']['relative']:.2f}x the overall"
        )
