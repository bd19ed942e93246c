"""Pinching: the loop narrows near zero force on reloading."""

import itertools
from typing import ClassVar

from ..._models.structural import StructuralBoucWen
from .base import AbstractEffect, RefitScales, model_as


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
        return (
            f"residual RMS near zero force is {where['near_zero_force']['relative']:.2f}x "
            f"and on reloading through it "
            f"{where['reloading_near_zero_force']['relative']:.2f}x the overall; the "
            f"fitted slip-lock takes up to {pinch:.0%} of the hysteretic stiffness "
            "there"
        )
