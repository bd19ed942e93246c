"""Driver lag: the field follows the command through first-order dynamics."""

from typing import ClassVar

from .base import (
    AbstractEffect,
    RefitScales,
    concentration,
    conclude,
    fitted,
    named_units,
    time_scale,
)


# Lags tried as starting points, in sample intervals: from a fraction of the record's
# resolution to the tens of milliseconds a coil's L/R and the fluid's response take
# at kHz rates.
LAGS_IN_SAMPLES = (1.0, 3.0, 10.0, 30.0, 100.0)


class DriverLag(AbstractEffect):
    """`ExtendedDamper`'s command_lag: the field w follows the command v as
    w' = (v - w)/command_lag (the coil's inductance, the driver's current loop and
    the fluid's own response), exact per sample. Seen only through the field's
    effect: with no field dependence in the model it has no direction to score."""

    name: ClassVar[str] = "driver_lag"
    parameters: ClassVar[tuple[str, ...]] = ("command_lag",)
    needs: ClassVar[str | None] = "field_dependence"
    meaning: ClassVar[str] = (
        "the field lags the command: after each switch the force reaches its new "
        "level over a time constant (the coil's inductance, the current driver, "
        "the fluid's response)"
    )

    def bounds(self, name, value, scales: RefitScales):
        if name == "command_lag":
            return (0.0, min(0.2 * scales.duration, 300.0 / scales.sample_rate))
        return None

    def starting_points(self, current, step, scales):
        # A lag is far from linear in its time constant beyond a sample or two: a
        # grid of lags besides the score step.
        models = super().starting_points(current, step, scales)
        models += [
            current.replace(command_lag=k / scales.sample_rate) for k in LAGS_IN_SAMPLES
        ]
        return models

    def always_refit(self):
        # The linearised score sees a lag as a one-sample spike at each switch, far
        # smaller than what a lag of many samples leaves.
        return True

    def score_screens(self):
        # Its direction at zero lag is d(force)/d(field) times the command's rate:
        # where the fitted field saturates at a small command (a field_knee of tens
        # per volt), d(force)/d(field) is nearly zero and so is the score, however
        # much a lag of milliseconds changes the force at each switch.
        return False

    def evidence(self, where, model):
        return conclude(
            [
                concentration(
                    where,
                    "after_switch",
                    "just after the command switches",
                    "where a lagging field shows",
                )
            ]
        )

    def units(self, *, time, input, output):
        return {"command_lag": named_units(time, input, output).time}

    def reading(self, values, errors, units):
        scale, unit = time_scale(values["command_lag"], units["command_lag"])
        lag = fitted(values, errors, units, "command_lag", scale, unit)
        return (
            f"the field follows the command with a time constant of {lag}: it "
            "reaches 63 % of a command step after one time constant and 95 % after "
            "three"
        )
