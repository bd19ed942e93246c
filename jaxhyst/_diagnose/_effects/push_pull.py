"""Push/pull asymmetry of a cyclic test."""

from typing import ClassVar

from .base import AbstractEffect


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
        share = where["even_part_rms"] / max(where["overall_rms"], 1e-300)
        return (
            f"{share:.0%} of the residual RMS is even in displacement (the same in "
            "push and pull at equal |x|), which a symmetric Bouc-Wen force cannot "
            f"produce; mean residual {where['push']['mean']:.3g} in push and "
            f"{where['pull']['mean']:.3g} in pull"
        )
