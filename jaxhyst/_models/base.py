"""The model interface shared by every hysteresis model.

A model is a pytree of parameters plus its physics. Its `vector_field(t, state, drive)`
has the diffrax signature (with `drive` what the model read from the input at `t`),
so the same model runs unchanged under the scan-RK4 simulator and under diffrax.
"""

import abc
from collections.abc import Callable
from typing import TYPE_CHECKING, ClassVar, Self

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float, Int

from .._inputs import InputPath
from .._smoothing import AbstractSmoothing


def as_parameter(value: ArrayLike) -> Array:
    """A parameter value as a strongly typed JAX array. Python scalars would give
    weakly typed arrays, and a weak/strong mismatch between calls recompiles.

    Model parameters are declared `eqx.field(converter=as_parameter)`: stored as
    arrays, so changing their values never recompiles, while the constructor (and a
    type checker) accepts floats."""
    array = jnp.asarray(value)
    if not jnp.issubdtype(array.dtype, jnp.inexact):
        array = array.astype(jnp.result_type(float))
    return jnp.asarray(array, dtype=array.dtype)


class Drive(eqx.Module):
    """What a model reads from the input at one time: the input and its rate."""

    u: Float[Array, ""]
    udot: Float[Array, ""]


SampleUpdate = Callable[[Array, Array, Array], Array]


class AbstractHysteresisModel(eqx.Module):
    """Base class of all models.

    Subclasses declare `parameter_names` (the fields that are model parameters, in a
    fixed order) and `state_size`, and implement `vector_field` and `output`.
    """

    if TYPE_CHECKING:
        # To a type checker an AbstractVar is a dataclass field, which would put
        # `smoothing` first among every subclass's positional parameters.
        smoothing: ClassVar[AbstractSmoothing]
    else:
        smoothing: eqx.AbstractVar[AbstractSmoothing]
    parameter_names: ClassVar[tuple[str, ...]]
    state_size: ClassVar[int]

    def drive(
        self,
        path: InputPath,
        t: Float[ArrayLike, ""],
        interval: Int[ArrayLike, ""] | None = None,
        frac: Float[ArrayLike, ""] | None = None,
    ) -> Drive:
        """Read the input at time `t`. Simulators that know which sample interval a
        stage lies in pass `interval` and `frac` (position inside it), which resolves
        the one-sided rate at sample instants exactly."""
        u, udot = read_input(path, t, interval, frac)
        return Drive(u, udot)

    @abc.abstractmethod
    def vector_field(
        self, t: Float[ArrayLike, ""], state: Float[Array, " s"], drive: Drive
    ) -> Float[Array, " s"]:
        """d(state)/dt."""

    @abc.abstractmethod
    def output(
        self, t: Float[ArrayLike, ""], state: Float[Array, " s"], drive: Drive
    ) -> Float[Array, ""]:
        """The measured quantity (displacement) for this state and input."""

    def initial_state(self, drive: Drive) -> Float[Array, " s"]:
        """The state at the first sample: a demagnetised (h = 0), resting system."""
        return jnp.zeros(self.state_size, jnp.result_type(drive.u))

    def sample_update(self, inputs: InputPath) -> "SampleUpdate | None":
        """An exact per-sample map applied after the ODE has been integrated across
        each sample interval, or None (the default: the ODE is the whole model).

        Models with fast *linear* parts (a stage seen through a mass-spring-damper)
        use it to propagate those parts exactly over the interval instead of
        integrating them with small RK4 steps. The returned function maps
        (state at the interval's start, ODE state at its end, interval) to the state
        at its end.
        """
        return None

    def parameters(self) -> dict[str, Array]:
        """The parameter values by name, in `parameter_names` order."""
        return {name: getattr(self, name) for name in self.parameter_names}

    def replace(self, **values: ArrayLike) -> Self:
        """A copy with some parameters replaced: `model.replace(k1=2.0)`."""
        unknown = sorted(set(values) - set(self.parameter_names))
        if unknown:
            raise ValueError(
                f"{type(self).__name__}.replace: unknown parameter(s) {unknown}; "
                f"this model has {list(self.parameter_names)}."
            )
        names = list(values)
        return eqx.tree_at(
            lambda m: [getattr(m, name) for name in names],
            self,
            [as_parameter(values[name]) for name in names],
        )

    def astype(self, dtype) -> Self:
        """A copy whose floating-point leaves have `dtype` (e.g. for float32 runs)."""
        return jax.tree.map(
            lambda x: (
                x.astype(dtype)
                if eqx.is_array(x) and jnp.issubdtype(x.dtype, jnp.floating)
                else x
            ),
            self,
        )


def read_input(
    path: InputPath,
    t: Float[ArrayLike, ""],
    interval: Int[ArrayLike, ""] | None,
    frac: Float[ArrayLike, ""] | None,
) -> tuple[Float[Array, ""], Float[Array, ""]]:
    """(u, udot) at `t`, on the given sample interval when one is known."""
    if interval is None or frac is None:
        return path.evaluate(t)
    return path.on_interval(interval, frac)


def hysteretic_rate(
    smoothing: AbstractSmoothing,
    h: Float[ArrayLike, ""],
    rate: Float[ArrayLike, ""],
    amplitude: Float[ArrayLike, ""],
    beta: Float[ArrayLike, ""],
    gamma: Float[ArrayLike, ""],
    n: Float[ArrayLike, ""],
) -> Float[Array, ""]:
    """The Bouc-Wen law, eq. 2 / 8 / 16:
    hdot = (A - (beta*sign(rate)*sign(h) + gamma)*|h|^n) * rate,
    which equals A*rate - beta*|rate|*|h|^(n-1)*h - gamma*rate*|h|^n."""
    s = smoothing
    h_pow = s.abs_pow(h, n)
    return jnp.asarray(
        (amplitude - (beta * s.sign(rate) * s.sign(h) + gamma) * h_pow) * rate
    )
