"""Driver lag: the field follows the command through one or two first-order
stages."""

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
    """`ExtendedDamper`'s command_lag and field_lag: the field follows the command
    through two first-order stages in series (the driver's current loop and the
    coil's L/R, then eddy currents and the fluid's own response), each exact per
    sample; field_lag = 0 is the single stage of Spencer et al. (their eta). Two
    stages follow a driver that settles like a second-order system, which one
    cannot. Seen only through the field's effect: with no field dependence in the
    model it has no direction to score."""

    name: ClassVar[str] = "driver_lag"
    parameters: ClassVar[tuple[str, ...]] = ("command_lag", "field_lag")
    forms: ClassVar[dict[str, tuple[str, ...]]] = {
        "first_order": ("command_lag",),
        "second_stage": ("field_lag",),
    }
    needs: ClassVar[str | None] = "field_dependence"
    meaning: ClassVar[str] = (
        "the field lags the command: after each switch the force reaches its new "
        "level over a time constant (the coil's inductance, the current driver, "
        "the fluid's response)"
    )

    def bounds(self, name, value, scales: RefitScales):
        if name in self.parameters:
            return (0.0, min(0.2 * scales.duration, 300.0 / scales.sample_rate))
        return None

    def sensitivity_parameters(self, model):
        # At zero lags both stages move the force alike (minus the command's rate
        # times d(force)/d(field)): one direction to score. Once adopted, both are
        # free parameters and need their own columns.
        return self.parameters if self.is_on(model) else ("command_lag",)

    def directions(self, columns, predicted, dt):
        return columns["command_lag"][:, None]

    def starting_points(self, current, step, scales):
        # A lag is far from linear in its time constant beyond a sample or two: a
        # grid of lags besides the score step, in one stage and split evenly over
        # two (the critically damped second-order driver; a refit cannot leave
        # the single stage for two, whose first-order change is the same).
        models = super().starting_points(current, step, scales)
        for k in LAGS_IN_SAMPLES:
            lag = k / scales.sample_rate
            models += [
                current.replace(command_lag=lag, field_lag=0.0),
                current.replace(command_lag=lag / 2, field_lag=lag / 2),
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
        return dict.fromkeys(self.parameters, named_units(time, input, output).time)

    def reading(self, values, errors, units):
        first, second = values["command_lag"], values["field_lag"]
        scale, unit = time_scale(max(first, second), units["command_lag"])
        lags = [fitted(values, errors, units, p, scale, unit) for p in self.parameters]
        if min(first, second) < 0.05 * max(first, second):
            main = lags[0] if first >= second else lags[1]
            return (
                f"the field follows the command with a time constant of {main} (a "
                "single first-order stage; the second is negligible): it reaches "
                "63 % of a command step after one time constant and 95 % after three"
            )
        return (
            f"the field follows the command through two first-order stages of {lags[0]} "
            f"and {lags[1]} (a step response that starts flat, like a second-order "
            f"driver's): it settles over about {scale * (first + second):.3g} {unit} "
            "(the mean delay, the two time constants' sum)"
        )
