"""Input bias: the hysteresis sees the drive early or late."""

from typing import ClassVar

from .base import (
    AbstractEffect,
    RefitScales,
    concentration,
    conclude,
    fitted,
    named_units,
    quantity,
    time_scale,
)


class InputBias(AbstractEffect):
    """`ExtendedPiezo`'s phi (a time shift of the drive, the paper's V = u(t + phi))
    and a first-order network between drive and actuator (input_lead, input_time)."""

    name: ClassVar[str] = "input_bias"
    parameters: ClassVar[tuple[str, ...]] = ("phi", "input_lead", "input_time")
    meaning: ClassVar[str] = (
        "the hysteresis responds to the drive early or late: a time shift of the "
        "drive (and an optional first-order network between drive and actuator)"
    )
    log_scaled: ClassVar[tuple[str, ...]] = ("input_time",)
    shape_parameters: ClassVar[tuple[str, ...]] = ("input_time",)
    forms: ClassVar[dict[str, tuple[str, ...]]] = {
        "time_shift": ("phi",),
        "first_order_network": ("input_lead", "input_time"),
    }

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
        return conclude(
            [
                concentration(
                    where,
                    "near_reversals",
                    "near reversals",
                    "where a time shift of the drive shows most",
                )
            ]
        )

    def units(self, *, time, input, output):
        u = named_units(time, input, output)
        return {"phi": u.time, "input_lead": "1", "input_time": u.time}

    def reading(self, values, errors, units):
        # V(t) = u(t + phi): with phi > 0 the hysteresis sees now what the drive
        # does phi later, i.e. it sees the drive early.
        phi, error = values["phi"], errors.get("phi")
        scale, unit = time_scale(phi, units["phi"])
        size = quantity(
            scale * abs(phi), None if error is None else scale * error, unit
        )
        if phi > 0:
            shift = f"the hysteresis sees the drive {size} early (phi > 0)"
        elif phi < 0:
            shift = f"the hysteresis sees the drive {size} late (phi < 0)"
        else:
            shift = "the hysteresis sees the drive without a time shift (phi = 0)"
        lead = values["input_lead"]
        if lead == 0:
            return (
                f"{shift}; no network between drive and actuator (input_lead = 0, "
                "so input_time is inert)"
            )
        # V = w + lead*(w - x), x' = (w - x)/input_time: V/W = (1 + s*T*(1 + lead))
        # / (1 + s*T), which passes a step at 1 + lead of its size at once and
        # settles to the whole step over T.
        passed = quantity(1 + lead, errors.get("input_lead"))
        if lead < -1:
            kind = "a lag that first moves against the drive"
        else:
            kind = "a lag" if lead < 0 else "a lead"
        scale, unit = time_scale(values["input_time"], units["input_time"])
        settle = fitted(values, errors, units, "input_time", scale, unit)
        return (
            f"{shift}; a first-order network between drive and actuator passes a "
            f"step of the drive at {passed} of its size at once ({kind}; 0 is a "
            f"pure RC low-pass, 1 no network) and settles to the whole step over "
            f"{settle}"
        )
