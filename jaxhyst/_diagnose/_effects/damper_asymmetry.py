"""Asymmetry: the damper's compression and extension strokes differ."""

from typing import ClassVar

from .base import (
    MEAN_GAP,
    AbstractEffect,
    Figure,
    RefitScales,
    carries,
    conclude,
    fitted,
    share,
)


class DamperAsymmetry(AbstractEffect):
    """`ExtendedDamper`'s skew (gamma -> gamma + skew*(beta + gamma)*sign(z): the
    hysteretic force saturates at different levels on the two sides) and
    damping_skew (c0 -> c0*(1 + damping_skew*sign(xdot)): the viscous damping
    differs by direction)."""

    name: ClassVar[str] = "asymmetry"
    parameters: ClassVar[tuple[str, ...]] = ("skew", "damping_skew")
    forms: ClassVar[dict[str, tuple[str, ...]]] = {
        "saturation_skew": ("skew",),
        "damping_skew": ("damping_skew",),
    }
    meaning: ClassVar[str] = (
        "compression and extension differ (the piston rod's area on one side, "
        "valving or seals that resist one direction more)"
    )

    def bounds(self, name, value, scales: RefitScales):
        # |skew| < 1 keeps both sides' saturation finite; the viscous coefficient
        # stays positive on both sides for |damping_skew| < 1.
        if name == "skew":
            return (-0.6, 0.6)
        if name == "damping_skew":
            return (-0.8, 0.8)
        return None

    def evidence(self, where, model):
        up = where["positive_velocity"]["mean"]
        down = where["negative_velocity"]["mean"]
        apart = round(abs(share(up - down, where["overall_rms"])), 2)
        means = (
            f"mean residual {up:.3g} at positive velocity vs {down:.3g} at negative "
            f"velocity, {apart:.2f}x the overall RMS apart"
        )
        return conclude(
            [
                carries(
                    where["even_part_rms"],
                    where["overall_rms"],
                    "the part even in velocity (the same at +v and -v)",
                    "which a symmetric damper cannot produce",
                ),
                Figure(True, f"the two directions differ on average ({means})")
                if apart >= MEAN_GAP
                else Figure(
                    False, f"the two directions do not differ on average ({means})"
                ),
            ]
        )

    def units(self, *, time, input, output):
        return {"skew": "1", "damping_skew": "1"}

    def reading(self, values, errors, units):
        skew, damping = values["skew"], values["damping_skew"]
        if skew > 0:
            side = "lower where z > 0 than where z < 0"
        elif skew < 0:
            side = "lower where z < 0 than where z > 0"
        else:
            side = "the same on both sides"
        if damping > 0:
            more = "positive velocity damped more"
        elif damping < 0:
            more = "negative velocity damped more"
        else:
            more = "both directions damped alike"
        return (
            f"the hysteretic force saturates {side} (saturation coefficient "
            f"(beta + gamma)*(1 + skew*sign(z)), skew = "
            f"{fitted(values, errors, units, 'skew')}); the viscous damping is "
            f"(1 + d)*c0 at positive velocity and (1 - d)*c0 at negative velocity "
            f"with d = damping_skew = {fitted(values, errors, units, 'damping_skew')} "
            f"({more})"
        )
