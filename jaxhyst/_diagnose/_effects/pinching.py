"""Pinching: the loop narrows near zero force on reloading."""

import itertools
from typing import ClassVar

from ..._models.structural import StructuralBoucWen
from .base import (
    ENERGY_UNIT,
    AbstractEffect,
    RefitScales,
    concentration,
    conclude,
    fitted,
    model_as,
)


class Pinching(AbstractEffect):
    """`StructuralBoucWen`'s two pinching forms, either or both: the Baber-Noori /
    BWBN slip-lock (the hysteretic rate drops near z = pinch_shift*zu on reloading,
    by up to `pinch`, grown in with the dissipated energy at `pinch_rate`, over a
    width set by `pinch_width`) and Sivaselvan-Reinhorn's series slip (each passage
    through zero force slips by up to `slip_length` times the largest displacement
    so far beyond the yield displacement zu, within a force window `slip_window`
    times the yield force): the first narrows the loop by the same share at every
    amplitude once the energy has grown it in, the second by a slip that opens with
    the largest excursion past yield."""

    name: ClassVar[str] = "pinching"
    parameters: ClassVar[tuple[str, ...]] = (
        "pinch",
        "pinch_shift",
        "pinch_width",
        "pinch_rate",
        "slip_length",
        "slip_window",
    )
    meaning: ClassVar[str] = (
        "the loop narrows near zero force on reloading (slip-lock: cracks closing, "
        "bolts slipping in their holes, gaps in connections)"
    )
    log_scaled: ClassVar[tuple[str, ...]] = ("pinch_width", "pinch_rate", "slip_window")
    # Each form's gain, then the shape parameters inert while it is zero.
    forms: ClassVar[dict[str, tuple[str, ...]]] = {
        "slip_lock": ("pinch", "pinch_shift", "pinch_width", "pinch_rate"),
        "series_slip": ("slip_length", "slip_window"),
    }
    shape_parameters: ClassVar[tuple[str, ...]] = tuple(
        p for own in forms.values() for p in own[1:]
    )

    def bounds(self, name, value, scales: RefitScales):
        return {
            "pinch": (0.0, 1.0),
            "pinch_shift": (-0.5, 1.5),
            "pinch_width": (0.02, 3.0),
            "pinch_rate": (0.05, 500.0),
            "slip_length": (0.0, 1.5),
            "slip_window": (0.01, 1.0),
        }.get(name)

    def fitted_dof(self, model):
        """A form left at zero fitted neither its gain nor its inert shape."""
        return max(sum(len(self.forms[name]) for name in self.forms_on(model)), 1)

    def starting_points(self, current, step, scales):
        # The score only sees `pinch` at the default shape; a pinched loop's shape
        # (where, how wide, how soon) is far from linear, so a grid is added.
        models = super().starting_points(current, step, scales)
        grid = itertools.product(
            (0.3, 0.6, 0.85), (0.0, 0.25, 0.5), (0.15, 0.4), (1.0, 20.0)
        )
        models += [
            current.replace(pinch=p, pinch_shift=q, pinch_width=w, pinch_rate=r)
            for p, q, w, r in grid
        ]
        # The series slip: how far it slips per passage, over how wide a window.
        models += [
            current.replace(slip_length=a, slip_window=w)
            for a, w in itertools.product((0.1, 0.3, 0.7), (0.05, 0.2))
        ]
        return models

    def always_refit(self):
        return True

    def evidence(self, where, model):
        model = model_as(model, StructuralBoucWen, self.name)
        pinch, slip = float(model.pinch), float(model.slip_length)
        why = "where a slip-lock shows"
        located = conclude(
            [
                concentration(where, "near_zero_force", "near zero force", why),
                concentration(
                    where,
                    "reloading_near_zero_force",
                    "on reloading through zero force",
                    why,
                ),
            ]
        )
        parts = []
        if pinch != 0.0 or slip == 0.0:
            parts.append(
                f"the fitted slip-lock takes up to {pinch:.0%} of the hysteretic "
                "stiffness near zero force"
            )
        if slip != 0.0:
            parts.append(
                f"the fitted series slip moves {slip:.0%} of the largest "
                "displacement beyond yield so far at each passage through zero force"
            )
        return f"{' and '.join(parts)}; {located}"

    def units(self, *, time, input, output):
        # zeta1 = pinch*(1 - exp(-pinch_rate*e)) is a share of the hysteretic rate;
        # the slip sits at pinch_shift*zu over a width pinch_width*zu*(...), zu the
        # saturation displacement; e is counted in max|F|*max|x|.
        return {
            "pinch": "1",
            "pinch_shift": "zu",
            "pinch_width": "zu",
            "pinch_rate": ENERGY_UNIT,
            "slip_length": "1",
            "slip_window": "F_y",
        }

    def reading(self, values, errors, units):
        def q(name, scale=1.0, unit=None):
            return fitted(values, errors, units, name, scale, unit)

        shape = (
            f"near z = {q('pinch_shift')} on reloading (zu: the hysteretic "
            f"saturation displacement), over a width {q('pinch_width')} times "
            f"(lambda + zeta1), grown in as 1 - exp(-pinch_rate*e) with e the "
            f"dissipated energy (pinch_rate = {q('pinch_rate')})"
        )
        if values["pinch"] == 0:
            lock = f"no slip-lock (pinch = 0), so its shape is inert: {shape}"
        else:
            lock = (
                f"a slip-lock takes up to {q('pinch', 100.0, '%')} of the hysteretic "
                f"stiffness {shape}"
            )
        window = (
            f"within a force window of {q('slip_window')} (F_y: the yield force "
            "(1 - alpha)*k*zu)"
        )
        if values["slip_length"] == 0:
            return f"{lock}; no series slip (slip_length = 0; its {window} is inert)"
        return (
            f"{lock}; a series slip of {q('slip_length', 100.0, '%')} of the largest "
            "displacement so far beyond the yield displacement zu at each passage "
            f"through zero force, {window}"
        )
