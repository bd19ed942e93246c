"""Which parameters a fit moves, within what bounds, and how they are scaled.

Swarm and refinement work in a unit box: each free parameter maps from [0, 1] to its
bounds, linearly or on a log scale (for a parameter that spans decades). They never
search raw values of wildly different magnitudes.
"""

from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float

from ._models.base import AbstractHysteresisModel, DataScales
from ._recording import Recording


# Exponents below 1 leave Table 2's stable classes (and |h|^n loses its derivative).
_HARD_FLOORS = {"n": 1.0, "nu": 1.0}
# With `stable_shape`, beta + gamma >= this share of beta: strictly inside Table 2.
_STABLE_MARGIN = 1e-6


class ParameterSpace(eqx.Module):
    """A box over some of a model's parameters; the others stay at the template's values.

    `bounds` maps each free parameter name to `(lower, upper)` in the model's units.
    `log_scale` names the free parameters searched on a log scale (bounds must then
    have one sign). Build the model's default space for a recording with
    `ParameterSpace.default(model, recording)`.

    `stable_shape=True` keeps every model the space gives inside Table 2's stable
    classes (for A > 0: beta >= 0 and beta + gamma > 0, a loop whose hysteretic
    displacement saturates) whatever the coordinates say, as hard floors on the
    model's beta and then gamma (`bouc_wen_shape().names`): a polish that steps out
    of them stops at their edge instead of fitting an unbounded element.
    """

    template: AbstractHysteresisModel
    names: tuple[str, ...] = eqx.field(static=True)
    log_scale: tuple[bool, ...] = eqx.field(static=True)
    lower: Float[Array, " d"]
    upper: Float[Array, " d"]
    floor: Float[Array, " d"]
    ceiling: Float[Array, " d"]
    frozen: Bool[Array, " d"]
    stable_shape: bool = eqx.field(static=True)

    def __init__(
        self,
        template: AbstractHysteresisModel,
        bounds: dict[str, tuple[float, float]],
        *,
        log_scale: tuple[str, ...] | list[str] = (),
        frozen: tuple[str, ...] | list[str] = (),
        stable_shape: bool = False,
    ):
        if not isinstance(template, AbstractHysteresisModel):
            raise TypeError(
                "ParameterSpace: template must be a jaxhyst model, got "
                f"{type(template).__name__}."
            )
        if not bounds:
            raise ValueError(
                "ParameterSpace: bounds is empty; name at least one parameter."
            )
        unknown = sorted(set(bounds) - set(template.parameter_names))
        if unknown:
            raise ValueError(
                f"ParameterSpace: {unknown} are not parameters of "
                f"{type(template).__name__} ({list(template.parameter_names)})."
            )
        bad_log = sorted(set(log_scale) - set(bounds))
        if bad_log:
            raise ValueError(
                f"ParameterSpace: log_scale names {bad_log} that are not free."
            )
        names = tuple(n for n in template.parameter_names if n in bounds)
        lower, upper = [], []
        for name in names:
            lo, hi = (float(v) for v in bounds[name])
            if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                raise ValueError(
                    f"ParameterSpace: bounds for {name!r} must be finite with lower < "
                    f"upper, got ({lo}, {hi})."
                )
            if name in log_scale and lo * hi <= 0:
                raise ValueError(
                    f"ParameterSpace: {name!r} is log-scaled but its bounds ({lo}, {hi}) "
                    "include zero; use a linear scale or bounds of one sign."
                )
            lower.append(lo)
            upper.append(hi)
        self.template = template
        self.names = names
        self.log_scale = tuple(n in log_scale for n in names)
        self.lower = jnp.asarray(lower)
        self.upper = jnp.asarray(upper)
        # Physical limits that hold even when a polish steps outside the box.
        floors = {**_HARD_FLOORS, **template.parameter_floors}
        self.floor = jnp.asarray([floors.get(n, -np.inf) for n in names])
        ceilings = template.parameter_ceilings
        self.ceiling = jnp.asarray([ceilings.get(n, np.inf) for n in names])
        # Frozen parameters keep the template's value whatever z says. The mask is
        # traced, so fits over different subsets of one space share a compilation.
        self.frozen = jnp.asarray([n in frozen for n in names], bool)
        if not isinstance(stable_shape, bool):
            raise TypeError(
                f"ParameterSpace: stable_shape must be True or False, got "
                f"{stable_shape!r}."
            )
        self.stable_shape = stable_shape

    @property
    def dimension(self) -> int:
        return len(self.names)

    def _scaled_bounds(self):
        log = jnp.asarray(self.log_scale)
        sign = jnp.where(log, jnp.sign(self.lower), 1.0)
        lo = jnp.where(log, jnp.log(jnp.abs(self.lower)), self.lower)
        hi = jnp.where(log, jnp.log(jnp.abs(self.upper)), self.upper)
        return log, sign, lo, hi

    def to_values(self, z: Float[ArrayLike, " d"]) -> Float[Array, " d"]:
        """Unit-box coordinates -> parameter values (z outside [0, 1] extrapolates,
        up to the model's physical limits: `floor` and `ceiling`)."""
        log, sign, lo, hi = self._scaled_bounds()
        scaled = lo + jnp.asarray(z) * (hi - lo)
        values = jnp.where(log, sign * jnp.exp(scaled), scaled)
        return jnp.clip(values, self.floor, self.ceiling)

    def to_unit(self, values: Float[ArrayLike, " d"]) -> Float[Array, " d"]:
        """Parameter values -> unit-box coordinates."""
        log, sign, lo, hi = self._scaled_bounds()
        values = jnp.asarray(values)
        scaled = jnp.where(log, jnp.log(jnp.abs(jnp.where(log, values, 1.0))), values)
        return (scaled - lo) / (hi - lo)

    def to_model(self, z: Float[ArrayLike, " d"]) -> AbstractHysteresisModel:
        """The template with the free parameters set from unit-box coordinates."""
        values = jnp.where(self.frozen, self._template_values(), self.to_values(z))
        model = eqx.tree_at(
            lambda m: [getattr(m, n) for n in self.names],
            self.template,
            [values[i] for i in range(self.dimension)],
        )
        return _inside_table_2(model) if self.stable_shape else model

    def _template_values(self) -> Float[Array, " d"]:
        return jnp.stack([jnp.asarray(getattr(self.template, n)) for n in self.names])

    def with_frozen(self, names: tuple[str, ...] | list[str]) -> "ParameterSpace":
        """The same space with `names` held at the template's values."""
        unknown = sorted(set(names) - set(self.names))
        if unknown:
            raise ValueError(
                f"ParameterSpace.with_frozen: {unknown} are not in the space."
            )
        mask = jnp.asarray([n in names for n in self.names], bool)
        return eqx.tree_at(lambda s: s.frozen, self, mask)

    def from_model(self, model: AbstractHysteresisModel) -> Float[Array, " d"]:
        """Unit-box coordinates of a model's free parameters."""
        return self.to_unit(
            jnp.stack([jnp.asarray(getattr(model, n)) for n in self.names])
        )

    def with_template(self, template: AbstractHysteresisModel) -> "ParameterSpace":
        return eqx.tree_at(lambda s: s.template, self, template)

    @classmethod
    def default(
        cls,
        template: AbstractHysteresisModel,
        scales: DataScales | Recording,
        *,
        gauge: bool = True,
        **options: Any,
    ) -> "ParameterSpace":
        """The model's default search box for a record: `template.default_bounds`,
        with `scales` a `DataScales` or a `Recording` (its scales are taken).
        `gauge=True` fixes the parameters that only rescale an internal variable
        (the piezo models' A1 = 1/max|u|); `options` are further keywords of the
        model's `default_bounds` (e.g. `nu_free=True` for `HystereticOscillator`).
        Models without a default box raise TypeError."""
        if not isinstance(template, AbstractHysteresisModel):
            raise TypeError(
                "ParameterSpace.default: template must be a jaxhyst model, got "
                f"{type(template).__name__}."
            )
        if not isinstance(scales, DataScales):
            scales = DataScales.of(scales)
        box = template.default_bounds(scales, gauge=gauge, **options)
        return cls(box.template, box.bounds, log_scale=box.log_scale)


def _inside_table_2(model: AbstractHysteresisModel) -> AbstractHysteresisModel:
    """`model` with its Bouc-Wen beta floored at 0 and then gamma at
    -(1 - margin)*beta (plus the smallest normal number, for beta = 0) where A > 0
    (Table 2's stable classes: beta >= 0 and beta + gamma > 0); unchanged inside
    them."""
    shape = model.bouc_wen_shape()
    beta_name, gamma_name = shape.names[1], shape.names[2]
    positive = shape.A > 0
    beta = jnp.where(positive, jnp.maximum(shape.beta, 0.0), shape.beta)
    tiny = jnp.finfo(jnp.result_type(beta)).tiny
    floor = -(1 - _STABLE_MARGIN) * beta + tiny
    gamma = jnp.where(positive, jnp.maximum(shape.gamma, floor), shape.gamma)
    return eqx.tree_at(
        lambda m: (getattr(m, beta_name), getattr(m, gamma_name)),
        model,
        (beta, gamma),
    )
