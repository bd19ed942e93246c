"""What the diagnosis engine needs to know about one effect of a catalogue.

An effect is a piece of physics a base model can leave out, written as a set of
parameters of the family's extended model: with its gains at zero the extended model
is the base model exactly. Everything the engine decides per effect lives on the
effect object (one final class per effect, one file each): how it is switched on and
off, where its parameters may go, which output directions the score test projects
on, where a refit starts, and the words of its evidence.
"""

import abc
from typing import Any, ClassVar, TypeVar

import equinox as eqx
import numpy as np

from ..._models.base import AbstractHysteresisModel


class RefitScales(eqx.Module):
    """The record's scales that bounds and starting points are expressed in."""

    sample_rate: float
    duration: float
    # How far each parameter must move to change the output by its RMS (from the
    # output's sensitivities at the current model).
    natural: dict[str, float]


class AbstractEffect(eqx.Module):
    """One catalogue entry: a stable `name`, the extended model's `parameters` that
    switch it on, what it means in an engineer's words, and its engine hooks.

    The defaults suit an effect whose parameters enter smoothly and vanish at zero:
    override a hook only where the physics needs it (a resonance that is switched
    on structurally, a time shift whose linearisation is poor).
    """

    name: ClassVar[str]
    parameters: ClassVar[tuple[str, ...]]
    meaning: ClassVar[str]
    # Parameters searched on a log scale in refits (positive time constants, rates).
    log_scaled: ClassVar[tuple[str, ...]] = ()
    # Parameters that only shape the effect (inert while its gains are zero).
    shape_parameters: ClassVar[tuple[str, ...]] = ()

    @property
    def gains(self) -> tuple[str, ...]:
        """The parameters whose zero switches the effect off."""
        return tuple(p for p in self.parameters if p not in self.shape_parameters)

    def is_on(self, model: AbstractHysteresisModel) -> bool:
        return any(float(getattr(model, p)) != 0.0 for p in self.gains)

    def switch_off(self, model: AbstractHysteresisModel) -> AbstractHysteresisModel:
        """`model` with this effect's gains at zero (the shape parameters are inert
        then, and kept)."""
        return model.replace(**{p: 0.0 for p in self.gains})

    def values(self, model: AbstractHysteresisModel) -> dict[str, float]:
        """This effect's parameter values in `model`, by name."""
        return {p: float(getattr(model, p)) for p in self.parameters}

    def take_from(
        self, model: AbstractHysteresisModel, source: AbstractHysteresisModel
    ) -> AbstractHysteresisModel:
        """`model` with this effect's parameters taken from `source`."""
        return model.replace(**self.values(source))

    def sensitivity_parameters(self, model: AbstractHysteresisModel) -> tuple[str, ...]:
        """The parameters whose output sensitivities the engine computes at
        `model` (all of them for a smooth effect)."""
        return self.parameters

    def directions(
        self,
        columns: dict[str, np.ndarray],
        predicted: np.ndarray,
        dt: float,
    ) -> np.ndarray:
        """The output directions the score test projects the residual on: by
        default the output's sensitivities to the effect's parameters at zero."""
        return np.stack([columns[p] for p in self.parameters], axis=1)

    def bounds(
        self, name: str, value: float, scales: RefitScales
    ) -> tuple[float, float] | None:
        """Refit bounds for one of this effect's parameters, or None for the
        engine's rule (the current value +- its natural scale)."""
        return None

    def starting_points(
        self,
        current: AbstractHysteresisModel,
        step: dict[str, float],
        scales: RefitScales,
    ) -> list[AbstractHysteresisModel]:
        """Models a refit may start from: the score test's Gauss-Newton `step` at
        several lengths (the linearisation rarely has the right size)."""
        return [
            current.replace(
                **{p: float(getattr(current, p)) + scale * v for p, v in step.items()}
            )
            for scale in (0.25, 0.5, 1.0, 2.0, 4.0)
        ]

    def always_refit(self) -> bool:
        """Refit whenever significant, even outside the strongest few: for effects
        the linearised score understates."""
        return False

    @abc.abstractmethod
    def evidence(self, where: dict[str, Any], model: AbstractHysteresisModel) -> str:
        """The location figures (`where`, from the family's `locate`) and fitted
        values (`model`) that support this effect, in words."""


ModelT = TypeVar("ModelT", bound=AbstractHysteresisModel)


def model_as(model: AbstractHysteresisModel, cls: type[ModelT], effect: str) -> ModelT:
    """`model` as its family's extended model class, or a TypeError naming the
    mismatch (an effect of one family asked about another family's model)."""
    if not isinstance(model, cls):
        raise TypeError(
            f"the {effect!r} effect acts on {cls.__name__} models, got "
            f"{type(model).__name__}; pass a model of the same family."
        )
    return model
