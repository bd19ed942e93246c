"""Field dependence: the damper's force parameters follow the command."""

import math
from typing import ClassVar

from .base import (
    AbstractEffect,
    RefitScales,
    carries,
    conclude,
    contrast,
    fitted,
)


# The knee is named (saturating or faster than affine) only beyond this many
# standard errors from zero.
SETTLED = 2.0


class FieldDependence(AbstractEffect):
    """`ExtendedDamper`'s field_alpha and field_damping (alpha and c0, and the
    internal dashpot with c0, grow by these shares at the record's peak |command|)
    and field_knee (0: affine in the command; > 0: the field saturates)."""

    name: ClassVar[str] = "field_dependence"
    parameters: ClassVar[tuple[str, ...]] = (
        "field_alpha",
        "field_damping",
        "field_knee",
    )
    meaning: ClassVar[str] = (
        "the damper's force follows the command: the MR fluid's yield force and "
        "viscous damping grow with the magnetic field (a damper of fixed field "
        "ignores the command)"
    )
    shape_parameters: ClassVar[tuple[str, ...]] = ("field_knee",)
    forms: ClassVar[dict[str, tuple[str, ...]]] = {"field_scaled": parameters}

    def bounds(self, name, value, scales: RefitScales):
        # A field that weakens the fluid by more than 90 % is not an MR damper;
        # a 100-fold growth at the peak command is beyond any published one
        # (Spencer et al. 1997: alpha x12 at 2.25 V). The knee: up to 20 (the
        # field's effect at the peak is then 1/21 of the affine one).
        if name in ("field_alpha", "field_damping"):
            return (-0.9, 100.0)
        if name == "field_knee":
            return (-0.5, 20.0)
        return None

    def starting_points(self, current, step, scales):
        # The force is linear in the gains for a fixed z: the score step is a good
        # start; a saturating field is tried at a few knees.
        models = super().starting_points(current, step, scales)
        at_step = current.replace(
            **{p: float(getattr(current, p)) + v for p, v in step.items()}
        )
        models += [at_step.replace(field_knee=knee) for knee in (0.5, 2.0)]
        return models

    def evidence(self, where, model):
        return conclude(
            [
                carries(
                    where["command_part_rms"],
                    where["overall_rms"],
                    "the part that follows the command (command x velocity, "
                    "command x direction of motion)",
                    "which a damper of fixed field cannot produce",
                ),
                contrast(
                    where,
                    "high_command",
                    "low_command",
                    "its RMS at high command is {ratio:.2f}x that at low command",
                ),
            ]
        )

    def units(self, *, time, input, output):
        # Relative growths at the record's peak |command| (the field's unit).
        return dict.fromkeys(self.parameters, "1")

    def reading(self, values, errors, units):
        # s = q/(1 + knee*q), q the command over the record's peak |command|: at
        # the peak the field acts at s = 1/(1 + knee) of an affine growth, so alpha
        # grows there by field_alpha/(1 + knee) (the error quoted is the gain's,
        # scaled alike).
        knee, error = values["field_knee"], errors.get("field_knee", math.nan)
        at_peak = 1 / max(1 + knee, 0.05)

        def percent(name):
            return fitted(values, errors, units, name, 100.0 * at_peak, "%")

        if not (math.isfinite(error) and abs(knee) > SETTLED * error):
            form = (
                "affine in the command (field_knee = "
                f"{fitted(values, errors, units, 'field_knee')}, within "
                f"{SETTLED:g} standard errors of 0 or not determined)"
            )
        else:
            kind = "saturating" if knee > 0 else "growing faster than affine"
            form = (
                f"{kind}: at the peak command the field acts at {at_peak:.0%} of an "
                f"affine growth (field_knee = "
                f"{fitted(values, errors, units, 'field_knee')})"
            )
        return (
            f"at the record's peak |command| the hysteretic force's scale alpha "
            f"grows by {percent('field_alpha')} and the viscous damping c0 (with "
            f"the internal dashpot, when present) by {percent('field_damping')} "
            f"over their values at zero command; {form}"
        )
