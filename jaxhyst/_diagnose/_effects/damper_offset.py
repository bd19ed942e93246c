"""Offset: the damper force's zero moves along the record."""

import math
from typing import ClassVar

import jax.numpy as jnp
import numpy as np

from ..._models.base import spline_drift
from ..._models.damper_extended import OFFSET_INTERVALS, OFFSET_TERMS
from .base import AbstractEffect, carries, conclude, named_units


# Where the reading samples the offset: a few points per spline interval.
_READING_POINTS = 8 * OFFSET_INTERVALS + 1


class DamperOffset(AbstractEffect):
    """`ExtendedDamper`'s offset spline (a uniform cubic B-spline in time over 24
    equal intervals of the record, coefficients offset1 ... offset26) added to the
    force: the accumulator's preload drifting as the gas warms, a load-cell zero
    wandering. The constant part is the base model's f0.

    A zero that wanders back and forth is not a polynomial of any degree the
    held-out blocks can check: on the damper suite's six offset-only records,
    Legendre terms to degree 8 (this effect's earlier form) left 0.27-1.09 noise
    sigmas of the truth's offset on the fitted samples and 0.41-3.7 on the
    held-out blocks, and higher degrees swing inside the blocks. The spline's
    coefficients each move the force within four intervals only, and refits hold
    their second differences small (`smooth`): the spline then bridges a held-out
    block as a smooth zero would (0.08-0.34 sigma left on the fitted samples,
    0.21-0.98 on the held-out blocks, same records), and the blocks judge it by
    interpolation. Under random motion (the white-noise tests this family reads)
    functions of time this slow are nearly orthogonal to the mechanics, except a
    stiffness acting on the displacement's slow components: a base fit can take up
    part of a wander that way (one suite record's base put a negative k0 there, and
    the offset's 20-step candidate refit did not lead it out)."""

    name: ClassVar[str] = "offset"
    # Its forms (polynomials, a spline) are all slow functions of time.
    form_in_loops: ClassVar[bool] = False
    parameters: ClassVar[tuple[str, ...]] = OFFSET_TERMS
    additive: ClassVar[tuple[str, ...]] = parameters
    forms: ClassVar[dict[str, tuple[str, ...]]] = {"spline": parameters}
    smooth: ClassVar[tuple[str, ...]] = parameters
    meaning: ClassVar[str] = (
        "the force's zero moves along the record, independently of the motion "
        "(the accumulator's preload changing as the damper warms, a load-cell or "
        "sensor offset drifting)"
    )

    def evidence(self, where, model):
        return conclude(
            [
                carries(
                    where["slow_trend_rms"],
                    where["overall_rms"],
                    "a slow trend (the residual's moving average over 1/25 of the "
                    "record)",
                )
            ]
        )

    def units(self, *, time, input, output):
        return dict.fromkeys(self.parameters, named_units(time, input, output).output)

    def reading(self, values, errors, units):
        # The offset as the force it adds: 26 coefficients read as one curve.
        s = jnp.linspace(-1.0, 1.0, _READING_POINTS)
        curve = np.asarray(spline_drift(s, tuple(values[n] for n in OFFSET_TERMS)))
        unit = units[OFFSET_TERMS[0]]
        unit = "" if unit in ("", "1") else f" {unit}"
        rise = curve[-1] - curve[0]
        spread = curve - curve.mean()
        coefficient_errors = [errors.get(n, math.nan) for n in OFFSET_TERMS]
        if all(math.isfinite(e) for e in coefficient_errors):
            certainty = (
                "its coefficients carry standard errors up to "
                f"{max(coefficient_errors):.2g}{unit}"
            )
        else:
            certainty = "its coefficients are not determined by this record"
        return (
            f"the force's zero moves by {rise:.3g}{unit} from the start of the record "
            f"to its end and wanders about its mean with an RMS of "
            f"{np.sqrt(np.mean(spread**2)):.3g}{unit}, between {spread.min():.3g} "
            f"and {spread.max():.3g}{unit} (a spline over 24 equal parts of the "
            f"record; {certainty}); the constant preload is the base's f0"
        )
