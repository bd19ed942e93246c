"""Piezo asymmetry: the ascending and descending branches are not mirror images."""

from typing import ClassVar

from .base import (
    MEAN_GAP,
    AbstractEffect,
    Figure,
    concentration,
    conclude,
    fitted,
    named_units,
    per,
    share,
    times,
)


class Asymmetry(AbstractEffect):
    """`ExtendedPiezo`'s eps (the paper's Delta_Phi), skew (different saturation
    on the two sides) and quad/cubic (a static bend of one end of the stroke)."""

    name: ClassVar[str] = "asymmetry"
    parameters: ClassVar[tuple[str, ...]] = ("eps", "quad", "cubic", "skew")
    forms: ClassVar[dict[str, tuple[str, ...]]] = {
        "input_offset": ("eps",),
        "static_bend": ("quad", "cubic"),
        "saturation_skew": ("skew",),
    }
    meaning: ClassVar[str] = (
        "the ascending and descending branches are not mirror images (the loop is "
        "wider, saturates sooner or is bent differently at one end of the stroke)"
    )

    def evidence(self, where, model):
        up, down = where["ascending"]["mean"], where["descending"]["mean"]
        apart = round(abs(share(up - down, where["overall_rms"])), 2)
        means = (
            f"mean residual {up:.3g} ascending vs {down:.3g} descending, "
            f"{apart:.2f}x the overall RMS apart"
        )
        branches = (
            Figure(True, f"the branches differ on average ({means})")
            if apart >= MEAN_GAP
            else Figure(False, f"the branches do not differ on average ({means})")
        )
        extremes = concentration(
            where,
            "extremes",
            "at the extremes of the stroke",
            "as a bend of one end of the stroke produces",
        )
        return conclude([branches, extremes])

    def units(self, *, time, input, output):
        # In the gauge the diagnosis fits in (A1 = 1/input_scale) the hysteretic
        # state h is dimensionless: hdot = eps*u*sign(udot) is 1/time, and gamma1
        # (which skew shifts) multiplies udot*|h|^n.
        u = named_units(time, input, output)
        return {
            "eps": per("1", times(u.input, u.time)),
            "quad": u.output,
            "cubic": u.output,
            "skew": per("1", u.input),
        }

    def reading(self, values, errors, units):
        def q(name):
            return fitted(values, errors, units, name)

        return (
            f"the hysteretic state's rate gains eps*u in the direction of travel "
            f"(eps = {q('eps')}; the paper's Delta_Phi), so the branches separate "
            f"differently at positive and negative drive; its saturation coefficient "
            f"is gamma1 + skew where h > 0 and gamma1 - skew where h < 0 (skew = "
            f"{q('skew')}); relative to the middle of the drive range, a static bend "
            f"adds quad = {q('quad')} at both ends alike and cubic = {q('cubic')} at "
            f"the top end (its opposite at the bottom)"
        )
