"""Push/pull asymmetry of a cyclic test."""

from typing import ClassVar

from .base import (
    MEAN_GAP,
    AbstractEffect,
    Figure,
    carries,
    conclude,
    fitted,
    share,
)


# |yield_skew| stays below this: a side whose shape term vanished would never yield.
MOST_SKEW = 0.9


class PushPullAsymmetry(AbstractEffect):
    """`StructuralBoucWen`'s yield_skew (push and pull yield at different levels:
    the shape term is scaled by 1 + yield_skew*sign(z)) and stiffness_skew
    (different post-yield stiffness)."""

    name: ClassVar[str] = "asymmetry"
    parameters: ClassVar[tuple[str, ...]] = ("yield_skew", "stiffness_skew")
    forms: ClassVar[dict[str, tuple[str, ...]]] = {
        "yield_skew": ("yield_skew",),
        "stiffness_skew": ("stiffness_skew",),
    }
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

    def bounds(self, name, value, scales):
        # 1 + yield_skew*sign(z) must stay positive on both sides.
        return (-MOST_SKEW, MOST_SKEW) if name == "yield_skew" else None

    def units(self, *, time, input, output):
        # Both are pure numbers: yield_skew scales the shape term, stiffness_skew
        # is a share of the post-yield term alpha*k*x.
        return {"yield_skew": "1", "stiffness_skew": "1"}

    def reading(self, values, errors, units):
        skew = values["yield_skew"]
        # (beta*sign(xdot*z) + gamma)*(1 + yield_skew*sign(z))*|z|^n: a larger shape
        # term saturates sooner, at a lower force.
        if skew > 0:
            lower = "lower in push (z > 0) than in pull"
        elif skew < 0:
            lower = "lower in pull (z < 0) than in push"
        else:
            lower = "the same in push and pull"
        ss = values["stiffness_skew"]
        stiffer = "push" if ss > 0 else "pull" if ss < 0 else "neither side"
        return (
            f"the hysteretic force saturates {lower} (the yield level is "
            "(1 + yield_skew*sign(z))^(-1/n) of the symmetric one, yield_skew = "
            f"{fitted(values, errors, units, 'yield_skew')}); the post-yield "
            "stiffness is (1 + s)*alpha*k in push and (1 - s)*alpha*k in pull with "
            f"s = stiffness_skew = {fitted(values, errors, units, 'stiffness_skew')} "
            f"({stiffer} stiffer)"
        )
