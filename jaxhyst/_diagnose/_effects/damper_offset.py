"""Offset: the damper force's zero moves along the record."""

from typing import ClassVar

from ..._models.damper_extended import OFFSET_TERMS
from .base import AbstractEffect, carries, conclude, fitted, named_units


class DamperOffset(AbstractEffect):
    """`ExtendedDamper`'s Legendre terms in time, degrees 1 to 8 (trend,
    curvature, wander, legendre4 ... legendre8), added to the force: the
    accumulator's preload drifting as the gas warms, a load-cell zero drifting.
    The constant part is the base model's f0. Eight degrees follow a zero that
    wanders back and forth up to four times over the record (a random walk smoothed
    over a quarter of it leaves a median 5 % of its RMS to degree 8, 12 % to degree
    5), not only one that creeps one way; under
    random motion (the white-noise tests this family reads) slow functions of time
    are nearly orthogonal to the mechanics, so the extra terms take nothing from
    the other effects, and the held-out blocks judge them by interpolation."""

    name: ClassVar[str] = "offset"
    parameters: ClassVar[tuple[str, ...]] = OFFSET_TERMS
    additive: ClassVar[tuple[str, ...]] = parameters
    meaning: ClassVar[str] = (
        "the force's zero moves along the record, independently of the motion "
        "(the accumulator's preload changing as the damper warms, a load-cell or "
        "sensor offset drifting)"
    )

    def evidence(self, where, model):
        return conclude(
            [
                carries(
                    where["slow_trend_rms"],
                    where["overall_rms"],
                    "a slow trend (the residual's moving average over 1/25 of the "
                    "record)",
                )
            ]
        )

    def units(self, *, time, input, output):
        return dict.fromkeys(self.parameters, named_units(time, input, output).output)

    def reading(self, values, errors, units):
        # trend*s + curvature*(s^2 - 1/3) + wander*(5 s^3 - 3 s)/2
        # + legendre4*P4(s) + ... + legendre8*P8(s), s from -1 to 1.
        def q(name, scale=1.0):
            return fitted(values, errors, units, name, scale)

        return (
            f"the force's zero moves by {q('trend', 2.0)} from the start of the record "
            f"to its end (a linear trend); its ends sit {q('curvature')} above its "
            f"middle (curvature); an S-shaped wander reaches {q('wander')} at the end "
            f"(its opposite at the start); the Legendre terms of degree 4 to 8, "
            f"{', '.join(q(f'legendre{k}') for k in range(4, 9))} at the end, follow "
            "a zero that goes back and forth; the constant preload is the base's f0"
        )
