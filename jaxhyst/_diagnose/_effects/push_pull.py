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
        return (
            f"mean residual {where['push']['mean']:.3g} in push vs "
            f"{where['pull']['mean']:.3g} in pull, and "
            f"{where['peaks']['relative']:.2f}x the overall RMS at the peaks"
        )
