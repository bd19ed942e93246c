"""Degradation: strength and/or stiffness fall as a cyclic test goes on."""

import math
from typing import ClassVar

from ..._models.structural import StructuralBoucWen
from .base import AbstractEffect, model_as


class Degradation(AbstractEffect):
    """`StructuralBoucWen`'s Baber-Wen degradation, driven by the dissipated
    energy e: strength through nu = 1 + strength_degradation*e, stiffness through
    eta = 1 + stiffness_degradation*e."""

    name: ClassVar[str] = "degradation"
    parameters: ClassVar[tuple[str, ...]] = (
        "strength_degradation",
        "stiffness_degradation",
    )
    meaning: ClassVar[str] = (
        "the specimen weakens and/or softens as the test goes on (cracking, "
        "crushing, bond loss, fastener wear): later cycles carry less force at the "
        "same displacement"
    )

    def evidence(self, where, model):
        energy = max(float(where["dissipated_energy"]), 0.0)
        model = model_as(model, StructuralBoucWen, self.name)
        n = float(model.n)
        nu = max(1 + float(model.strength_degradation) * energy, 1e-2)
        eta = max(1 + float(model.stiffness_degradation) * energy, 1e-2)
        # At the end of the test: the hysteretic force saturates at nu^(-1/n) of its
        # first level and the hysteretic tangent is 1/eta of its first value.
        strength = 1 - nu ** (-1 / n)
        stiffness = 1 - 1 / eta
        if abs(strength) > 2 * abs(stiffness):
            which = "mainly strength"
        elif abs(stiffness) > 2 * abs(strength):
            which = "mainly stiffness"
        else:
            which = "both strength and stiffness"
        excess = where["late_peak_force_excess"]
        peaks = (
            f"; at the peaks of the last third the base model's force is off by "
            f"{excess:.3g} on average (negative: too strong)"
            if math.isfinite(excess)
            else ""
        )
        return (
            f"{which} degrade: by the end of the test (dissipated energy "
            f"{energy:.3g} x max|F| max|x|) the hysteretic strength is down "
            f"{strength:.0%} and its stiffness {stiffness:.0%}; residual RMS in the "
            f"last third of the test is {where['last_third']['relative']:.2f}x and in "
            f"the first third {where['first_third']['relative']:.2f}x the overall"
            f"{peaks}"
        )
