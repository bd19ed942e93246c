"""Which parameters a fit moves, within what bounds, and how they are scaled.

Swarm and refinement work in a unit box: each free parameter maps from [0, 1] to its
bounds, linearly or on a log scale (for a parameter that spans decades). They never
search raw values of wildly different magnitudes.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float

from ._models.base import AbstractHysteresisModel
from ._models.bouc_wen import (
    BoucWen,
    CorrectedPiezoBoucWen,
    PiezoBoucWen,
    PiezoStage,
)
from ._models.oscillator import HystereticOscillator


# Exponents below 1 leave Table 2's stable classes (and |h|^n loses its derivative).
_HARD_FLOORS = {"n": 1.0, "nu": 1.0}


class ParameterSpace(eqx.Module):
    """A box over some of a model's parameters; the others stay at the template's values.

    `bounds` maps each free parameter name to `(lower, upper)` in the model's units.
    `log_scale` names the free parameters searched on a log scale (bounds must then
    have one sign). Build the usual space for a recording with
    `ParameterSpace.default(model, recording)`.
    """

    template: AbstractHysteresisModel
    names: tuple[str, ...] = eqx.field(static=True)
    log_scale: tuple[bool, ...] = eqx.field(static=True)
    lower: Float[Array, " d"]
    upper: Float[Array, " d"]
    floor: Float[Array, " d"]
    frozen: Bool[Array, " d"]

    def __init__(
        self,
        template: AbstractHysteresisModel,
        bounds: dict[str, tuple[float, float]],
        *,
        log_scale: tuple[str, ...] | list[str] = (),
        frozen: tuple[str, ...] | list[str] = (),
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
        self.floor = jnp.asarray([_HARD_FLOORS.get(n, -jnp.inf) for n in names])
        # Frozen parameters keep the template's value whatever z says. The mask is
        # traced, so fits over different subsets of one space share a compilation.
        self.frozen = jnp.asarray([n in frozen for n in names], bool)

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
        """Unit-box coordinates -> parameter values (z outside [0, 1] extrapolates)."""
        log, sign, lo, hi = self._scaled_bounds()
        scaled = lo + jnp.asarray(z) * (hi - lo)
        return jnp.maximum(jnp.where(log, sign * jnp.exp(scaled), scaled), self.floor)

    def to_unit(self, values: Float[ArrayLike, " d"]) -> Float[Array, " d"]:
        """Parameter values -> unit-box coordinates."""
        log, sign, lo, hi = self._scaled_bounds()
        values = jnp.asarray(values)
        scaled = jnp.where(log, jnp.log(jnp.abs(jnp.where(log, values, 1.0))), values)
        return (scaled - lo) / (hi - lo)

    def to_model(self, z: Float[ArrayLike, " d"]) -> AbstractHysteresisModel:
        """The template with the free parameters set from unit-box coordinates."""
        values = jnp.where(self.frozen, self._template_values(), self.to_values(z))
        return eqx.tree_at(
            lambda m: [getattr(m, n) for n in self.names],
            self.template,
            [values[i] for i in range(self.dimension)],
        )

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
        input_scale: float,
        output_scale: float,
        duration: float,
        *,
        sample_rate: float | None = None,
        gauge: bool = True,
    ) -> "ParameterSpace":
        """Bounds scaled to the data: `input_scale` = max |u|, `output_scale` = max |y|.

        For the piezo models the hysteretic variable is made dimensionless: with
        `gauge=True` (default) A1 is fixed at 1/input_scale, which removes the
        h -> c*h symmetry (any fit with A1 != 0 maps onto it exactly); then k1, k2 are
        O(output/input) and O(output), beta1, gamma1 O(1/input). Pass `gauge=False` to
        search all six (the redundant direction is then reported, not removed).
        """
        su, sy = float(input_scale), float(output_scale)
        if not (su > 0 and sy > 0 and duration > 0):
            raise ValueError(
                "ParameterSpace.default: input_scale, output_scale and duration must be "
                "positive; a constant input or output cannot identify a model."
            )
        piezo = {
            "k1": (-3 * sy / su, 3 * sy / su),
            "k2": (-5 * sy, 5 * sy),
            "A1": (-3 / su, 3 / su),
            # |beta1|, |gamma1| * max|u| up to 50: the loop may saturate within 2 % of
            # the input range (the paper's Table 4 sets reach ~37).
            "beta1": (-50 / su, 50 / su),
            "gamma1": (-50 / su, 50 / su),
            "n": (1.0, 3.0),
        }
        if isinstance(template, (PiezoBoucWen, CorrectedPiezoBoucWen, PiezoStage)):
            bounds = dict(piezo)
            log: list[str] = []
            if gauge:
                del bounds["A1"]
                template = template.replace(A1=1.0 / su)
            if isinstance(template, CorrectedPiezoBoucWen):
                bounds["phi"] = (-0.05 * duration, 0.05 * duration)
                bounds["eps"] = (-2.0 / (su * duration), 2.0 / (su * duration))
            if isinstance(template, PiezoStage):
                nyquist = 0.5 * (sample_rate or 1000.0)
                bounds["natural_frequency"] = (2.0 / duration, 0.5 * nyquist)
                bounds["damping_ratio"] = (1e-3, 3.0)
                log += ["natural_frequency", "damping_ratio"]
            return cls(template, bounds, log_scale=log)
        if isinstance(template, BoucWen):
            bounds = {
                "k": (1e-3 * sy / su, 10 * sy / su),
                "alpha": (0.0, 1.0),
                "A": (-3.0, 3.0),
                "beta": (-10 / su, 10 / su),
                "gamma": (-10 / su, 10 / su),
                "n": (1.0, 3.0),
            }
            return cls(template.replace(D=1.0), bounds, log_scale=["k"])
        if isinstance(template, HystereticOscillator):
            # u is a force, y a displacement: stiffness ~ input/output.
            k = su / sy
            bounds = {
                "mass": (
                    k / (2 * np.pi * 0.25 * (sample_rate or 1000.0)) ** 2,
                    k * (duration / (2 * np.pi)) ** 2,
                ),
                "damping": (1e-4 * k, 1.0 * k),
                "stiffness": (1e-2 * k, 1e2 * k),
                "alpha": (1e-2 * k, 1e2 * k),
                "beta_gamma": (-10 / sy, 10 / sy),
                "beta_delta": (-10 / sy, 10 / sy),
            }
            return cls(
                template,
                bounds,
                log_scale=["mass", "damping", "stiffness", "alpha"],
            )
        raise TypeError(
            f"ParameterSpace.default: no default bounds for {type(template).__name__}; "
            "build ParameterSpace(template, bounds) yourself."
        )
