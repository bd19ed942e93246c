"""Stage dynamics: the stage's mass and damping matter."""

import dataclasses
import math
from typing import ClassVar

import numpy as np

from ..._models.base import AbstractHysteresisModel
from ..._models.extended import ExtendedPiezo
from .base import (
    AbstractEffect,
    Figure,
    RefitScales,
    concentration,
    conclude,
    determined,
    fitted,
    model_as,
    named_units,
    per,
)


# The residual's dominant frequency is "near" the fitted resonance when the two are
# within this factor of each other: the residual a missing resonance leaves peaks
# within its half-power band (about 2*zeta*fn wide), and a factor 1.5 either side
# spans that band for damping ratios up to about 0.3; further away, the peak is
# something else.
NEAR_RESONANCE = 1.5


class Dynamics(AbstractEffect):
    """`ExtendedPiezo` with `dynamic=True`: the static response seen through a
    mass-spring-damper (natural_frequency, damping_ratio). Switched on by the
    model's structure, not by a gain."""

    name: ClassVar[str] = "dynamics"
    parameters: ClassVar[tuple[str, ...]] = ("natural_frequency", "damping_ratio")
    forms: ClassVar[dict[str, tuple[str, ...]]] = {"second_order": parameters}
    meaning: ClassVar[str] = (
        "the stage's mass and damping matter: the output lags (and may ring) after "
        "fast changes (a mechanical resonance)"
    )
    log_scaled: ClassVar[tuple[str, ...]] = ("natural_frequency", "damping_ratio")

    def is_on(self, model):
        return model_as(model, ExtendedPiezo, self.name).dynamic

    def switch_off(self, model):
        piezo = model_as(model, ExtendedPiezo, self.name)
        return dataclasses.replace(piezo, dynamic=False)

    def take_from(self, model, source):
        source = model_as(source, ExtendedPiezo, self.name)
        return model_as(model, ExtendedPiezo, self.name).with_dynamics(
            float(source.natural_frequency), float(source.damping_ratio)
        )

    def undetermined(self, values, errors, correlations):
        # A resonance is its frequency: switched on by the model's structure, it
        # has no gain, and a frequency the record does not pin down is no finding.
        name = "natural_frequency"
        return () if determined(values[name], errors.get(name)) else (name,)

    def sensitivity_parameters(self, model):
        # Without the stage in the model, its parameters move nothing.
        return self.parameters if self.is_on(model) else ()

    def directions(self, columns, predicted, dt):
        """First-order effect of a fast stage on the output: y ~ y_s - a1*y_s' -
        a2*y_s'' with a1 = 2*zeta/omega and a2 = 1/omega^2."""
        first = np.gradient(predicted, dt)
        second = np.gradient(first, dt)
        return -np.stack([first, second], axis=1)

    def bounds(self, name, value, scales: RefitScales):
        if name == "natural_frequency":
            return (2.0 / scales.duration, 0.5 * scales.sample_rate)
        if name == "damping_ratio":
            return (5e-3, 5.0)
        return None

    def starting_points(self, current, step, scales):
        # The score's step is in (a1, a2) of `directions`; a resonance is far from
        # linear in them, so a grid over frequencies and dampings is added.
        fs = scales.sample_rate
        a1 = step.get("natural_frequency", 0.0)
        a2 = step.get("damping_ratio", 0.0)
        points = []
        if a2 > 0 and a1 > 0:
            omega = 1 / math.sqrt(a2)
            zeta = min(2.0, max(0.01, a1 * omega / 2))
            points.append((min(0.45 * fs, omega / (2 * math.pi)), zeta))
        points += [(fs / d, z) for d in (40, 20, 10, 5, 2.5) for z in (0.05, 0.2, 0.5)]
        piezo = model_as(current, ExtendedPiezo, self.name)
        starts: list[AbstractHysteresisModel] = [
            piezo.with_dynamics(f, z) for f, z in points
        ]
        return starts

    def always_refit(self):
        # The linearised score understates a resonance (far from linear in
        # 1/omega^2), so a significant dynamics candidate is always refitted.
        return True

    def evidence(self, where, model):
        piezo = model_as(model, ExtendedPiezo, self.name)
        peak = float(where["dominant_frequency_hz"])
        resonance = float(piezo.natural_frequency)
        if not piezo.dynamic:
            frequency = Figure(False, "the model has no stage resonance to compare")
        elif not (peak > 0 and resonance > 0):
            frequency = Figure(
                False, "the record is too short for a dominant residual frequency"
            )
        elif max(peak / resonance, resonance / peak) <= NEAR_RESONANCE:
            frequency = Figure(
                True,
                f"the residual's dominant frequency ({peak:.3g} Hz) is near the "
                f"fitted resonance ({resonance:.3g} Hz)",
            )
        else:
            frequency = Figure(
                False,
                f"the residual's dominant frequency ({peak:.3g} Hz) is not at the "
                f"fitted resonance ({resonance:.3g} Hz)",
            )
        fast = concentration(
            where, "fast_rate", "at fast rates", "where a stage's inertia shows"
        )
        return conclude([frequency, fast], instead="the held-out gain")

    def units(self, *, time, input, output):
        # omega = 2*pi*natural_frequency in the record's time: cycles per time unit.
        u = named_units(time, input, output)
        return {
            "natural_frequency": "Hz" if u.time == "s" else per("1", u.time),
            "damping_ratio": "1",
        }

    def reading(self, values, errors, units):
        frequency = fitted(values, errors, units, "natural_frequency")
        zeta = values["damping_ratio"]
        damping = fitted(values, errors, units, "damping_ratio")
        if zeta >= 1:
            ringing = "overdamped: the stage lags fast changes without ringing"
        elif zeta > 0:
            ringing = f"it rings after fast changes, quality factor 1/(2 zeta) = {1 / (2 * zeta):.3g}"
        else:
            ringing = "undamped"
        return (
            f"stage resonance at {frequency} with damping ratio {damping} ({ringing})"
        )
