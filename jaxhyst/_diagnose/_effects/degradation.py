"""Degradation: strength and/or stiffness fall as a cyclic test goes on."""

import math
from typing import ClassVar

from ..._models.structural import StructuralBoucWen
from .base import (
    ENERGY_UNIT,
    MEAN_GAP,
    AbstractEffect,
    Figure,
    RefitScales,
    concentration,
    conclude,
    contrast,
    fitted,
    model_as,
    named_units,
    per,
    share,
)


# A fitted loss of strength or stiffness smaller than this by the end of the test
# is not named (it is below what a cyclic test's scatter resolves).
NEGLIGIBLE = 0.01
# One of strength and stiffness "mainly" degrades when its loss is this multiple
# of the other's.
MAINLY = 2.0


def _change(loss: float) -> str:
    if loss > 0:
        return f"down {loss:.0%}"
    # The rates are floored at zero: a loss of zero (or -0.0) is no change.
    return "unchanged" if loss == 0 else f"up {-loss:.0%}"


class Degradation(AbstractEffect):
    """`StructuralBoucWen`'s Baber-Wen degradation, driven by the dissipated
    energy e and by the largest displacement so far, p = max|x|: strength through
    nu = 1 + strength_degradation*e + peak_strength_degradation*p, stiffness through
    eta = 1 + stiffness_degradation*e + peak_stiffness_degradation*p. Real members
    degrade with both (Park-Ang's damage index), RC members from the cracking that
    precedes yield; a test whose amplitudes only grow cannot tell the two drivers
    apart, an earthquake-like history can."""

    name: ClassVar[str] = "degradation"
    parameters: ClassVar[tuple[str, ...]] = (
        "strength_degradation",
        "stiffness_degradation",
        "peak_strength_degradation",
        "peak_stiffness_degradation",
    )
    forms: ClassVar[dict[str, tuple[str, ...]]] = {
        "energy": ("strength_degradation", "stiffness_degradation"),
        "peak_excursion": ("peak_strength_degradation", "peak_stiffness_degradation"),
    }
    meaning: ClassVar[str] = (
        "the specimen weakens and/or softens as the test goes on (cracking, "
        "crushing, bond loss, fastener wear): later cycles carry less force at the "
        "same displacement"
    )

    def bounds(self, name, value, scales: RefitScales):
        # The rates only degrade (`StructuralBoucWen.parameter_floors`): the box
        # starts at zero. A strengthening is what a static stiffening of the member
        # looks like under growing amplitudes, and it is not this effect.
        reach = scales.natural.get(name, math.nan)
        if not (math.isfinite(reach) and reach > 0):
            reach = 2 * abs(value) + 1e-12
        return (0.0, max(value, 0.0) + reach)

    def evidence(self, where, model):
        return f"{self._fitted(where, model)}; {self._located(where)}"

    def _fitted(self, where, model) -> str:
        """The fitted loss of strength and stiffness by the end of the test."""
        energy = max(float(where["dissipated_energy"]), 0.0)
        model = model_as(model, StructuralBoucWen, self.name)
        n = float(model.n)
        # The largest |x| of the record (set by `around`; unset, no peak term).
        peak = float(model.displacement_scale)
        nu, eta = (
            float(f)
            for f in model.degradation_factors(energy, peak if peak < 1e29 else 0.0)
        )
        # At the end of the test: the hysteretic force saturates at nu^(-1/n) of its
        # first level and the hysteretic tangent is 1/eta of its first value. Judged
        # as quoted (whole percent).
        strength = round(1 - nu ** (-1 / n), 2)
        stiffness = round(1 - 1 / eta, 2)
        end = f"by the end of the test (dissipated energy {energy:.3g} x max|F| max|x|)"
        if max(abs(strength), abs(stiffness)) < NEGLIGIBLE:
            return (
                f"{end} the fitted strength and stiffness change by under "
                f"{NEGLIGIBLE:.0%}"
            )
        if abs(strength) >= MAINLY * abs(stiffness):
            which = "mainly the strength changes"
        elif abs(stiffness) >= MAINLY * abs(strength):
            which = "mainly the stiffness changes"
        else:
            which = "both strength and stiffness change"
        return (
            f"{which}: {end} the fitted hysteretic strength is {_change(strength)} "
            f"and its stiffness {_change(stiffness)}"
        )

    def _located(self, where) -> str:
        """What the location figures say about a change along the test."""
        figures = [
            concentration(
                where,
                "last_third",
                "in the last third of the test",
                "where accumulated damage shows most",
            ),
            contrast(
                where,
                "last_third",
                "first_third",
                "its RMS in the last third is {ratio:.2f}x that in the first",
            ),
        ]
        excess = float(where["late_peak_force_excess"])
        gap = round(share(abs(excess), where["overall_rms"]), 2)
        if math.isfinite(excess) and gap >= MEAN_GAP:
            off = (
                f"by {abs(excess):.3g} on average ({gap:.2f}x the overall RMS) at the "
                "peaks of the last third"
            )
            figures.append(
                Figure(True, f"the base model's force is too large {off}")
                if excess < 0
                else Figure(
                    False,
                    f"the base model's force is too small {off}, which a weakening "
                    "specimen does not produce",
                )
            )
        return conclude(figures)

    def units(self, *, time, input, output):
        per_peak = per("1", named_units(time, input, output).input)
        return {
            "strength_degradation": ENERGY_UNIT,
            "stiffness_degradation": ENERGY_UNIT,
            "peak_strength_degradation": per_peak,
            "peak_stiffness_degradation": per_peak,
        }

    def reading(self, values, errors, units):
        def q(name, unit=None):
            # The energy unit is spelled out in the words.
            return fitted(values, errors, units, name, unit=unit)

        return (
            f"the strength factor nu grows by {q('strength_degradation', '1')} and "
            f"the stiffness factor eta by {q('stiffness_degradation', '1')} per "
            "max|F|·max|x| of dissipated energy (about a quarter of an "
            "elastic-perfectly-plastic cycle at the peak amplitude), and by "
            f"{q('peak_strength_degradation')} and "
            f"{q('peak_stiffness_degradation')} per unit of the largest "
            "displacement reached so far: the "
            "hysteretic force's ceiling falls as nu^(-1/n) and its tangent as 1/eta"
        )
