"""Pinching: the loop narrows near zero force on reloading."""

import itertools
from typing import ClassVar

from ..._models.structural import StructuralBoucWen
from .base import (
    ENERGY_UNIT,
    AbstractEffect,
    RefitScales,
    concentration,
    conclude,
    fitted,
    model_as,
)


class Pinching(AbstractEffect):
    """`StructuralBoucWen`'s Baber-Noori / BWBN slip-lock: the hysteretic rate
    drops near z = pinch_shift*zu on reloading, by up to `pinch` (grown in with the
    dissipated energy at `pinch_rate`, over a width set by `pinch_width`)."""

    name: ClassVar[str] = "pinching"
    parameters: ClassVar[tuple[str, ...]] = (
        "pinch",
        "pinch_shift",
        "pinch_width",
        "pinch_rate",
    )
    meaning: ClassVar[str] = (
        "the loop narrows near zero force on reloading (slip-lock: cracks closing, "
        "bolts slipping in their holes, gaps in connections)"
    )
    log_scaled: ClassVar[tuple[str, ...]] = ("pinch_width", "pinch_rate")
    shape_parameters: ClassVar[tuple[str, ...]] = (
        "pinch_shift",
        "pinch_width",
        "pinch_rate",
    )

    def bounds(self, name, value, scales: RefitScales):
        return {
            "pinch": (0.0, 1.0),
            "pinch_shift": (-0.5, 1.5),
            "pinch_width": (0.02, 3.0),
            "pinch_rate": (0.05, 500.0),
        }.get(name)

    def starting_points(self, current, step, scales):
        # The score only sees `pinch` at the default shape; a pinched loop's shape
        # (where, how wide, how soon) is far from linear, so a grid is added.
        models = super().starting_points(current, step, scales)
        grid = itertools.product(
            (0.3, 0.6, 0.85), (0.0, 0.25, 0.5), (0.15, 0.4), (1.0, 20.0)
        )
        models += [
            current.replace(pinch=p, pinch_shift=q, pinch_width=w, pinch_rate=r)
            for p, q, w, r in grid
        ]
        return models

    def always_refit(self):
        return True

    def evidence(self, where, model):
        pinch = float(model_as(model, StructuralBoucWen, self.name).pinch)
        why = "where a slip-lock shows"
        located = conclude(
            [
                concentration(where, "near_zero_force", "near zero force", why),
                concentration(
                    where,
                    "reloading_near_zero_force",
                    "on reloading through zero force",
                    why,
                ),
            ]
        )
        return (
            f"the fitted slip-lock takes up to {pinch:.0%} of the hysteretic "
            f"stiffness near zero force; {located}"
        )

    def units(self, *, time, input, output):
        # zeta1 = pinch*(1 - exp(-pinch_rate*e)) is a share of the hysteretic rate;
        # the slip sits at pinch_shift*zu over a width pinch_width*zu*(...), zu the
        # saturation displacement; e is counted in max|F|*max|x|.
        return {
            "pinch": "1",
            "pinch_shift": "zu",
            "pinch_width": "zu",
            "pinch_rate": ENERGY_UNIT,
        }

    def reading(self, values, errors, units):
        def q(name, scale=1.0, unit=None):
            return fitted(values, errors, units, name, scale, unit)

        shape = (
            f"near z = {q('pinch_shift')} on reloading (zu: the hysteretic "
            f"saturation displacement), over a width {q('pinch_width')} times "
            f"(lambda + zeta1), grown in as 1 - exp(-pinch_rate*e) with e the "
            f"dissipated energy (pinch_rate = {q('pinch_rate')})"
        )
        if values["pinch"] == 0:
            return f"no slip-lock (pinch = 0), so its shape is inert: {shape}"
        return (
            f"a slip-lock takes up to {q('pinch', 100.0, '%')} of the hysteretic "
            f"stiffness {shape}"
        )
