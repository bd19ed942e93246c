"""Roll-off: an internal dashpot in series, the force rolls off at low velocity."""

from typing import ClassVar

from .base import (
    AbstractEffect,
    RefitScales,
    concentration,
    conclude,
    fitted,
)


class Rolloff(AbstractEffect):
    """`ExtendedDamper`'s rolloff: the compliance of a dashpot c1 in series with the
    Bouc-Wen element and c0 (Spencer et al. 1997's c1), rolloff =
    damping_scale/c1, 0 rigid."""

    name: ClassVar[str] = "rolloff"
    parameters: ClassVar[tuple[str, ...]] = ("rolloff",)
    forms: ClassVar[dict[str, tuple[str, ...]]] = {"series_dashpot": parameters}
    meaning: ClassVar[str] = (
        "the force rolls off at low velocity near reversals: the fluid's yield "
        "element acts through an internal dashpot in series (Spencer et al.'s c1), "
        "so the force-velocity loop passes smoothly through zero velocity"
    )

    def bounds(self, name, value, scales: RefitScales):
        # Up to an internal dashpot of a fifth of the record's typical force per
        # velocity; beyond it the dashpot, not the fluid, would carry the force.
        if name == "rolloff":
            return (0.0, 5.0)
        return None

    def starting_points(self, current, step, scales):
        # The roll-off's shape is far from linear in the compliance: a grid too.
        models = super().starting_points(current, step, scales)
        models += [current.replace(rolloff=r) for r in (0.03, 0.1, 0.3, 1.0)]
        return models

    def evidence(self, where, model):
        return conclude(
            [
                concentration(
                    where,
                    "near_reversals",
                    "near velocity reversals",
                    "where a series dashpot rolls the force off",
                ),
                concentration(
                    where, "approaching_reversals", "while decelerating into a reversal"
                ),
                concentration(
                    where, "leaving_reversals", "while accelerating out of a reversal"
                ),
            ]
        )

    def units(self, *, time, input, output):
        # A compliance in units of the record's rms(F)/rms(xdot).
        return {"rolloff": "1"}

    def reading(self, values, errors, units):
        rolloff = values["rolloff"]
        ratio = (
            f"about {1 / rolloff:.3g} times the record's typical force per velocity, "
            "rms(F)/rms(xdot)"
            if rolloff > 0
            else "rigid"
        )
        return (
            f"an internal dashpot in series, rolloff = "
            f"{fitted(values, errors, units, 'rolloff')} (its compliance in units "
            f"of rms(xdot)/rms(F)): the dashpot c1 is {ratio}; below the velocity "
            "at which c1 carries the yield force, the force falls off towards zero "
            "instead of holding the yield level"
        )
