"""Piezo asymmetry: the ascending and descending branches are not mirror images."""

from typing import ClassVar

from .base import AbstractEffect


class Asymmetry(AbstractEffect):
    """`ExtendedPiezo`'s eps (the paper's Delta_Phi), skew (different saturation
    on the two sides) and quad/cubic (a static bend of one end of the stroke)."""

    name: ClassVar[str] = "asymmetry"
    parameters: ClassVar[tuple[str, ...]] = ("eps", "quad", "cubic", "skew")
    meaning: ClassVar[str] = (
        "the ascending and descending branches are not mirror images (the loop is "
        "wider, saturates sooner or is bent differently at one end of the stroke)"
    )

    def evidence(self, where, model):
        return (
            f"mean residual {where['ascending']['mean']:.3g} on the ascending vs "
            f"{where['descending']['mean']:.3g} on the descending branch, and "
            f"{where['extremes']['relative']:.2f}x the overall RMS at the extremes of "
            "the stroke (a bend against the input)"
        )
