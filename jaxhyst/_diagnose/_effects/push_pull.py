"""Push/pull asymmetry of a cyclic test."""

from typing import ClassVar

from .base import (
    MEAN_GAP,
    AbstractEffect,
    Figure,
    carries,
    conclude,
    fitted,
    named_units,
    power,
    share,
)


class PushPullAsymmetry(AbstractEffect):
    """`StructuralBoucWen`'s skew (the hysteretic force saturates at different
    levels in push and pull) and stiffness_skew (different post-yield stiffness)."""

    name: ClassVar[str] = "asymmetry"
    parameters: ClassVar[tuple[str, ...]] = ("skew", "stiffness_skew")
    meaning: ClassVar[str] = (
        "push and pull differ (unsymmetric reinforcement, axial load, a wall "
        "rocking on one toe, a connection loaded against its grain)"
    )

    def evidence(self, where, model):
        overall = where["overall_rms"]
        even = carries(
            where["even_part_rms"],
            overall,
            "the part even in displacement (the same in push and pull at equal |x|)",
            "which a symmetric Bouc-Wen force cannot produce",
        )
        # An odd misfit (a wrong stiffness) gives push and pull means of opposite
        # signs; only means of the same sign, both sizeable, say push and pull differ.
        push, pull = where["push"]["mean"], where["pull"]["mean"]
        smaller = round(share(min(abs(push), abs(pull)), overall), 2)
        same_sign = push * pull > 0 and smaller >= MEAN_GAP
        means = Figure(
            same_sign,
            f"the mean residual has the same sign in push ({push:.3g}) and pull "
            f"({pull:.3g}), at least {smaller:.2f}x the overall RMS"
            if same_sign
            else "",
        )
        return conclude([even, means])

    def units(self, *, time, input, output):
        # With A = 1, z is a displacement and gamma*|z|^n is a pure number; the
        # post-yield term alpha*k*stiffness_skew*|x| is a share of alpha*k*x.
        u = named_units(time, input, output)
        return {"skew": power(u.input, "-n"), "stiffness_skew": "1"}

    def reading(self, values, errors, units):
        skew = values["skew"]
        # gamma + skew*sign(z): a larger gamma saturates sooner, at a lower force.
        if skew > 0:
            lower = "lower in push (z > 0) than in pull"
        elif skew < 0:
            lower = "lower in pull (z < 0) than in push"
        else:
            lower = "the same in push and pull"
        ss = values["stiffness_skew"]
        stiffer = "push" if ss > 0 else "pull" if ss < 0 else "neither side"
        return (
            f"the hysteretic force saturates {lower} (gamma + skew*sign(z), skew = "
            f"{fitted(values, errors, units, 'skew')}); the post-yield stiffness is "
            f"(1 + s)*alpha*k in push and (1 - s)*alpha*k in pull with s = "
            f"stiffness_skew = {fitted(values, errors, units, 'stiffness_skew')} "
            f"({stiffer} stiffer)"
        )
