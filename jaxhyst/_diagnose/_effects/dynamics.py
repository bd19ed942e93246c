"""Stage dynamics: the stage's mass and damping matter."""

import dataclasses
import math
from typing import ClassVar

import numpy as np

from ..._models.base import AbstractHysteresisModel
from ..._models.extended import ExtendedPiezo
from .base import AbstractEffect, RefitScales, model_as


class Dynamics(AbstractEffect):
    """`ExtendedPiezo` with `dynamic=True`: the static response seen through a
    mass-spring-damper (natural_frequency, damping_ratio). Switched on by the
    model's structure, not by a gain."""

    name: ClassVar[str] = "dynamics"
    parameters: ClassVar[tuple[str, ...]] = ("natural_frequency", "damping_ratio")
    meaning: ClassVar[str] = (
        "the stage's mass and damping matter: the output lags and rings after "
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
        return (
            f"residual dominated by {where['dominant_frequency_hz']:.3g} Hz content and "
            f"fast rates ({where['fast_rate']['relative']:.2f}x)"
        )
