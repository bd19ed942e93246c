"""Input bias: the hysteresis sees the drive early or late."""

from typing import ClassVar

from .base import AbstractEffect, RefitScales


class InputBias(AbstractEffect):
    """`ExtendedPiezo`'s phi (a time shift of the drive, the paper's V = u(t + phi))
    and a first-order network between drive and actuator (input_lead, input_time)."""

    name: ClassVar[str] = "input_bias"
    parameters: ClassVar[tuple[str, ...]] = ("phi", "input_lead", "input_time")
    meaning: ClassVar[str] = (
        "the hysteresis responds to the input slightly early or late (a time "
        "shift of the drive as the operator sees it)"
    )
    log_scaled: ClassVar[tuple[str, ...]] = ("input_time",)
    shape_parameters: ClassVar[tuple[str, ...]] = ("input_time",)

    def bounds(self, name, value, scales: RefitScales):
        if name == "input_time":
            return (4.0 / scales.sample_rate, 2.0)
        if name == "input_lead":
            return (-2.5, 3.0)
        if name == "phi":
            reach = min(0.05 * scales.duration, 0.5)
            return (value - reach, value + reach)
        return None

    def starting_points(self, current, step, scales):
        # The linearisation of a time shift is poor beyond a few samples: add a
        # grid of shifts, and of networks (an RC lag or a lead, 5-50 ms).
        models = super().starting_points(current, step, scales)
        shifts = [s * 1e-3 for s in (0.5, 1, 2, 5, 10, 20, 50, 100)]
        models += [current.replace(phi=sign * s) for s in shifts for sign in (1, -1)]
        models += [
            current.replace(input_lead=lead, input_time=time)
            for lead in (-0.9, -0.5, 0.5, 1.0)
            for time in (0.005, 0.02, 0.05)
        ]
        return models

    def evidence(self, where, model):
        return (
            f"residual near reversals is {where['near_reversals']['relative']:.2f}x "
            "the overall RMS, as a time shift of the drive produces"
        )
