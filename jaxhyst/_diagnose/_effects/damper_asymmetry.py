"""Asymmetry: the damper's compression and extension strokes differ."""

from typing import ClassVar

import numpy as np

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


# Valve widths tried as starting points, in RMS piston velocities: a valve that
# switches within a tenth of the typical velocity to one that is never fully open.
VALVE_WIDTHS = (0.1, 0.3, 1.0)


class DamperAsymmetry(AbstractEffect):
    """`ExtendedDamper`'s skew (gamma -> gamma + skew*(beta + gamma)*sign(z): the
    hysteretic force saturates at different levels on the two sides), damping_skew
    (c0 -> c0*(1 + damping_skew*switch(xdot)): the viscous damping differs by
    direction) and valve_width (the band of velocities over which the damping
    switches sides, in RMS piston velocities; 0 switches at once, as sign(xdot))."""

    name: ClassVar[str] = "asymmetry"
    parameters: ClassVar[tuple[str, ...]] = ("skew", "damping_skew", "valve_width")
    # Inert while damping_skew is zero.
    shape_parameters: ClassVar[tuple[str, ...]] = ("valve_width",)
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
        if name == "valve_width":
            return (0.0, 2.0)
        return None

    def sensitivity_parameters(self, model):
        # At valve_width = 0 the force does not move with it (it enters squared):
        # no column to score. Once the effect is in the model all three are free
        # parameters and need their columns (the width's is zero while it is).
        return self.parameters if self.is_on(model) else ("skew", "damping_skew")

    def directions(self, columns, predicted, dt):
        return np.stack([columns["skew"], columns["damping_skew"]], axis=1)

    def starting_points(self, current, step, scales):
        # The width has no first-order direction at zero: a grid of widths with
        # the score step (whose damping_skew is the abrupt switch's).
        models = super().starting_points(current, step, scales)
        for width in VALVE_WIDTHS:
            for scale in (1.0, 2.0):
                moved = {
                    p: float(getattr(current, p)) + scale * v for p, v in step.items()
                }
                models.append(current.replace(**moved, valve_width=width))
        return models

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
        return {"skew": "1", "damping_skew": "1", "valve_width": "1"}

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
            f"({more}), {_switch(values, errors, units)}"
        )


def _switch(values, errors, units) -> str:
    """How the damping switches sides, in words."""
    if values["valve_width"] == 0.0 or values["damping_skew"] == 0.0:
        return "switching at once at zero velocity"
    width = fitted(values, errors, units, "valve_width")
    return (
        f"switching gradually over a band of velocities (valve_width = {width} RMS "
        "piston velocities: xdot/sqrt(xdot^2 + width^2) instead of sign(xdot))"
    )
