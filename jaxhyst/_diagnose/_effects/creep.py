"""Creep: slow relaxation of the output driven by the input."""

import math
from typing import ClassVar

from ..._models.extended import CREEP_TIMES
from .base import (
    AbstractEffect,
    Figure,
    concentration,
    conclude,
    fitted,
    named_units,
    per,
    time_scale,
)


# The relaxation times of the modes, fastest first (ExtendedPiezo's creep_times,
# in seconds: the piezo family's records are in real time).
_TIMES: tuple[float, ...] = CREEP_TIMES

# Creep's fastest relaxation: a first-order relaxation faster than this is a viscous
# element's (`RateDependence`), not creep's.
FASTEST_CREEP = min(_TIMES)


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
    forms: ClassVar[dict[str, tuple[str, ...]]] = {"relaxation_modes": parameters}
    meaning: ClassVar[str] = (
        "the output keeps drifting for seconds after the input changes or "
        "holds (slow relaxation driven by the input)"
    )

    def evidence(self, where, model):
        if not math.isfinite(where["after_hold"]["relative"]):
            figure = Figure(
                False,
                "the recording has no holds, where a relaxation would show alone",
            )
        else:
            figure = concentration(
                where,
                "after_hold",
                "in the seconds after a hold begins",
                "where the output relaxes with the drive at rest",
            )
        return conclude([figure])

    def units(self, *, time, input, output):
        # y += creep_i*(c_i - u) with c_i the input low-passed over the mode's time.
        u = named_units(time, input, output)
        return dict.fromkeys(self.parameters, per(u.output, u.input))

    def reading(self, values, errors, units):
        # After a step du the mode's term starts at -creep_i*du and decays to 0:
        # the output moves on by creep_i*du over the mode's time.
        modes = []
        for name, tau in zip(self.parameters, _TIMES, strict=True):
            scale, unit = time_scale(tau, "s")
            modes.append(
                f"{fitted(values, errors, units, name)} over {scale * tau:g} {unit}"
            )
        return (
            "after a step of the drive the output moves on, per unit of the step, "
            "by " + ", ".join(modes) + " (positive: on in the step's direction, as "
            "creep; negative: back, as relaxation)"
        )
