"""Creep: slow relaxation of the output driven by the input."""

import math
from typing import ClassVar

from .base import AbstractEffect


class Creep(AbstractEffect):
    """`ExtendedPiezo`'s four relaxation modes (30 ms to 30 s, one per decade:
    logarithmic creep spans decades)."""

    name: ClassVar[str] = "creep"
    parameters: ClassVar[tuple[str, ...]] = (
        "creep_faster",
        "creep_fast",
        "creep_slow",
        "creep_slower",
    )
    meaning: ClassVar[str] = (
        "the output keeps drifting for seconds after the input changes or "
        "holds (slow relaxation driven by the input)"
    )

    def evidence(self, where, model):
        relative = where["after_hold"]["relative"]
        if not math.isfinite(relative):
            return (
                "the recording has no holds, so the slow relaxation shows only as "
                "a lag that grows over seconds after the input's level changes"
            )
        return (
            f"residual in the 2 s after holds begin is {relative:.2f}x the overall RMS"
        )
