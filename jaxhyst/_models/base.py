"""The model interface shared by every hysteresis model.

A model is a pytree of parameters plus its physics. Its `vector_field(t, state, drive)`
has the diffrax signature (with `drive` what the model read from the input at `t`),
so the same model runs unchanged under the scan-RK4 simulator and under diffrax.
"""

import abc
import dataclasses
import functools
import math
from collections.abc import Callable, Collection, Iterator
from typing import TYPE_CHECKING, ClassVar, Generic, NamedTuple, Self, TypeVar, cast

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, Int

from .._inputs import InputPath
from .._recording import Recording, RecordingError
from .._smoothing import AbstractSmoothing, ExactSign


if TYPE_CHECKING:
    from .._simulate import RK4
    from .structural import StructuralBoucWen


def as_parameter(value: ArrayLike) -> Array:
    """A parameter value as a strongly typed JAX array. Python scalars would give
    weakly typed arrays, and a weak/strong mismatch between calls recompiles.

    Model parameters are declared `eqx.field(converter=as_parameter)`: stored as
    arrays, so changing their values never recompiles, while the constructor (and a
    type checker) accepts floats."""
    array = value if isinstance(value, jax.Array) else np.asarray(value)
    if not jnp.issubdtype(array.dtype, jnp.inexact):
        array = array.astype(jnp.result_type(float))
    return jnp.asarray(array)


def smoothing_field():
    """The `smoothing` field of a model: keyword-only, `ExactSign` by default (the
    paper's sign; pass a smoothing rule where gradients cross reversals)."""
    return eqx.field(default_factory=ExactSign, kw_only=True)


class AbstractDrive(eqx.Module):
    """What a model reads from its inputs at one time: at least the input `u` and its
    rate `udot`. Each model's `drive` returns one kind, which its `vector_field`,
    `output` and `initial_state` read (`AbstractHysteresisModel[ThatDrive]`)."""

    u: eqx.AbstractVar[Float[Array, ""]]
    udot: eqx.AbstractVar[Float[Array, ""]]


class Drive(AbstractDrive):
    """What a model of one input reads at one time: the input and its rate."""

    u: Float[Array, ""]
    udot: Float[Array, ""]


DriveT = TypeVar("DriveT", bound=AbstractDrive)


SampleUpdate = Callable[[Array, Array, Array], Array]


# The magnitudes a fit computes with: squared errors of signals beyond this range
# overflow (or underflow) in double precision, so their peaks must lie within it.
SCALE_RANGE = (1e-150, 1e150)


def signal_scales(
    values: Float[ArrayLike, " n"],
    role: str,
    owner: str = "DataScales",
    *,
    span: str = "the whole record",
    constant: bool = True,
) -> tuple[float, float]:
    """The peak max|x| and the rms of a recorded input or output (`role`, over
    `span`, as messages say), checked first so that neither overflows nor
    underflows: its peak is measured, not its square (a signal that is zero
    throughout: 0 and 0). Raises `RecordingError`
    (its `cli` in the command line's words, its `kind` "constant" or "scale") for a
    constant signal (unless not `constant`: `DataScales` says that), and for one
    whose peak is non-zero and outside `SCALE_RANGE`."""
    x = np.asarray(values, dtype=np.float64)
    peak = float(np.max(np.abs(x)))
    option = "--input" if role == "input" else "--output"
    if constant and float(np.ptp(x)) == 0:
        problem = (
            f"the {role} is constant ({float(x[0]):.6g}) over {span}; a constant "
            "signal cannot identify a model"
        )
        raise RecordingError(
            f"{problem}; check the column selection.",
            owner=owner,
            cli=f"{problem}; check {option}, or pick --start/--end where it varies.",
            kind="constant",
        )
    if peak == 0:
        return 0.0, 0.0
    low, high = SCALE_RANGE
    if not low <= peak <= high:
        size = "large" if peak > high else "small"
        problem = (
            f"the {role} peaks at {peak:.3g}, too {size} to fit in double precision "
            f"(squared errors {'overflow' if size == 'large' else 'underflow'}; "
            f"peaks from {low:g} to {high:g} are fine)"
        )
        fix = "rescale it: express it in other units"
        raise RecordingError(
            f"{problem}; {fix}.", owner=owner, cli=f"{problem}; {fix}.", kind="scale"
        )
    # Within SCALE_RANGE the squares lie between 1e-300 and 1e300: neither overflow
    # nor underflow, so the rms is computed as it is everywhere else.
    return peak, float(np.sqrt(np.mean(np.square(x))))


class DataScales(eqx.Module):
    """The scales of a record that default search bounds are set from: peaks
    (max|u|, max|y|), rms values, duration and sample rate, all positive and finite,
    and the peak of each further input (`more_input_peaks`, e.g. an MR damper's
    command voltage; empty for one input). Build one from a recording with
    `DataScales.of(recording)`."""

    input_peak: float = eqx.field(converter=float)
    output_peak: float = eqx.field(converter=float)
    input_rms: float = eqx.field(converter=float)
    output_rms: float = eqx.field(converter=float)
    duration: float = eqx.field(converter=float)
    sample_rate: float = eqx.field(converter=float)
    more_input_peaks: tuple[float, ...] = eqx.field(
        converter=lambda peaks: tuple(float(p) for p in peaks), default=()
    )

    def __check_init__(self):
        for name, label in (
            ("input_peak", "max|u|"),
            ("output_peak", "max|y|"),
            ("input_rms", "rms(u)"),
            ("output_rms", "rms(y)"),
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                why = (
                    "a constant input or output cannot identify a model"
                    if value == 0
                    else "rescale the data (other units), or compute the rms on "
                    "scaled values (DataScales.of does)"
                )
                raise ValueError(
                    f"DataScales: {name} ({label}) = {value:g} must be positive and "
                    f"finite; {why}."
                )
        for name in ("duration", "sample_rate"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(
                    f"DataScales: {name} = {value:g} must be positive and finite; "
                    "pass a record of at least two samples."
                )

    @classmethod
    def of(cls, recording: Recording) -> "DataScales":
        """The scales of `recording` (anything with `.u`, `.y`, `.duration` and
        `.sample_rate`, such as a `Recording`)."""
        missing = [
            name
            for name in ("u", "y", "duration", "sample_rate")
            if not hasattr(recording, name)
        ]
        if missing:
            raise TypeError(
                f"DataScales.of: expected a Recording (with .u, .y, .duration and "
                f".sample_rate), got {type(recording).__name__} without {missing}."
            )
        u, y = np.asarray(recording.u), np.asarray(recording.y)
        more = np.asarray(getattr(recording, "more_inputs", np.zeros((0, u.size))))
        owner = f"DataScales.of({getattr(recording, 'name', 'recording')!r})"
        input_peak, input_rms = signal_scales(u, "input", owner, constant=False)
        output_peak, output_rms = signal_scales(y, "output", owner, constant=False)
        return cls(
            input_peak=input_peak,
            output_peak=output_peak,
            input_rms=input_rms,
            output_rms=output_rms,
            duration=float(recording.duration),
            sample_rate=float(recording.sample_rate),
            more_input_peaks=tuple(float(np.max(np.abs(row))) for row in more),
        )


class BoucWenShape(eqx.Module):
    """A model's Bouc-Wen shape parameters (A, beta, gamma, n, D; D = 1 where the
    model has none), as arrays (traceable), and the model's names for them (`names`:
    those of A, beta, gamma, n, then D where the model has one). Iterating gives
    (A, beta, gamma, n, D): `is_bibo_stable(*shape)`."""

    A: Float[Array, ""]
    beta: Float[Array, ""]
    gamma: Float[Array, ""]
    n: Float[Array, ""]
    D: Float[Array, ""]
    names: tuple[str, ...] = eqx.field(static=True)

    def __init__(
        self,
        A: Float[ArrayLike, ""],
        beta: Float[ArrayLike, ""],
        gamma: Float[ArrayLike, ""],
        n: Float[ArrayLike, ""],
        D: Float[ArrayLike, ""] | None = None,
        *,
        names: tuple[str, ...],
    ):
        if len(names) != (4 if D is None else 5):
            raise ValueError(
                f"BoucWenShape: names {names} must name A, beta, gamma, n"
                + (" and D." if D is not None else "; pass D to name five.")
            )
        self.A = jnp.asarray(A)
        self.beta = jnp.asarray(beta)
        self.gamma = jnp.asarray(gamma)
        self.n = jnp.asarray(n)
        self.D = jnp.ones_like(self.A) if D is None else jnp.asarray(D)
        self.names = tuple(names)

    def __iter__(self) -> Iterator[Float[Array, ""]]:
        return iter((self.A, self.beta, self.gamma, self.n, self.D))


class StageDynamics(NamedTuple):
    """A second-order stage a model's output is seen through,
    ydd/omega^2 + (2 zeta/omega) yd + y = y_static, and the drift added after it."""

    omega: float
    """The stage's natural angular frequency (rad/s)."""
    zeta: float
    """Its damping ratio."""
    drift: Callable[[np.ndarray], np.ndarray]
    """The output's drift at the given times, added after the stage."""


@functools.cache
def _positional_fields(cls: type) -> tuple[str, ...]:
    return tuple(f.name for f in dataclasses.fields(cls) if not f.kw_only)


@functools.cache
def _setting_fields(cls: type) -> tuple[str, ...]:
    skipped = {*cls.parameter_names, *cls.unlisted_fields}
    return tuple(f.name for f in dataclasses.fields(cls) if f.name not in skipped)


class _ParameterNames:
    """`parameter_names` of a model class that does not list them: its positional
    fields (the ones `Model(*values)` takes), in their declared order."""

    def __get__(self, instance, owner: type) -> tuple[str, ...]:
        return _positional_fields(owner)


class _SettingNames:
    """`setting_names` of a model class: its fields but the parameters and the
    `unlisted_fields`, in their declared order."""

    def __get__(self, instance, owner: type) -> tuple[str, ...]:
        return _setting_fields(owner)


class AbstractHysteresisModel(eqx.Module, Generic[DriveT]):
    """Base class of all models, generic in the kind of drive (`AbstractDrive`) the
    model reads: `drive` returns one, and `vector_field`, `output` and
    `initial_state` read it.

    A model's parameters (`parameter_names`) are its positional fields, in their
    declared order; keyword-only fields are its settings (`setting_names`: the
    normalisers set from a record, static options), the smoothing among them. A
    subclass may list `parameter_names` itself instead. Subclasses declare
    `state_size`, implement `vector_field` and `output`, and answer for themselves
    what other code asks of a model: the solver it is simulated with
    (`default_solver`), what makes its output lag the drive (`lag_reason`,
    `time_shift`, `stage_dynamics`, `quasi_static`: compensation), and its exports
    (`c_export_parameters`, `opensees_model`). The defaults say "none" or refuse.
    """

    if TYPE_CHECKING:
        # To a type checker an AbstractVar is a dataclass field, which would put
        # `smoothing` first among every subclass's positional parameters.
        smoothing: ClassVar[AbstractSmoothing]
        # Derived from the fields at run time (`_ParameterNames`, `_SettingNames`).
        parameter_names: ClassVar[tuple[str, ...]]
        setting_names: ClassVar[tuple[str, ...]]
    else:
        smoothing: eqx.AbstractVar[AbstractSmoothing]
        parameter_names = _ParameterNames()
        setting_names = _SettingNames()
    state_size: ClassVar[int]
    # Fields that are neither parameters nor settings: the smoothing (a model file
    # stores it on its own) and, in subclasses, ways of computing.
    unlisted_fields: ClassVar[tuple[str, ...]] = ("smoothing",)
    # Physical lower limits of parameters (by name) that fits keep even when a
    # polish steps outside its box (`ParameterSpace.floor`), beyond the shared ones
    # (n >= 1, nu >= 1).
    parameter_floors: ClassVar[dict[str, float]] = {}
    # Physical upper limits, likewise (`ParameterSpace.ceiling`): a share that
    # cannot pass one, say.
    parameter_ceilings: ClassVar[dict[str, float]] = {}
    # Parameters an earlier jaxhyst had and this one has not (by name: what
    # replaced them), so that loading an old model file says why it cannot.
    retired_parameters: ClassVar[dict[str, str]] = {}
    # The inputs the model reads, in the order an `InputPath` carries them (`values`,
    # then each row of `channels`). Models of more than one input override it.
    input_names: ClassVar[tuple[str, ...]] = ("u",)
    # Whether OpenSees has a uniaxial material for the model (`opensees_model`).
    has_opensees_material: ClassVar[bool] = False

    def drive(
        self,
        path: InputPath,
        t: Float[ArrayLike, ""],
        interval: Int[ArrayLike, ""] | None = None,
        frac: Float[ArrayLike, ""] | None = None,
    ) -> DriveT:
        """Read the input at time `t`. Simulators that know which sample interval a
        stage lies in pass `interval` and `frac` (position inside it), which resolves
        the one-sided rate at sample instants exactly. The default reads the one
        input (a `Drive`); a model whose drive is another kind overrides it."""
        u, udot = read_input(path, t, interval, frac)
        return cast(DriveT, Drive(u, udot))

    @abc.abstractmethod
    def vector_field(
        self, t: Float[ArrayLike, ""], state: Float[Array, " s"], drive: DriveT
    ) -> Float[Array, " s"]:
        """d(state)/dt."""

    @abc.abstractmethod
    def output(
        self, t: Float[ArrayLike, ""], state: Float[Array, " s"], drive: DriveT
    ) -> Float[Array, ""]:
        """The measured quantity (displacement) for this state and input."""

    def initial_state(self, drive: DriveT) -> Float[Array, " s"]:
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

    def has_sample_update(self, inputs: InputPath) -> bool:
        """Whether `sample_update(inputs)` gives a map. Override it where building
        the map computes (outside `jit`, each such computation compiles)."""
        return self.sample_update(inputs) is not None

    def held_at_zero(self, names: Collection[str]) -> Self:
        """This model with the parameters `names` (each at zero) held there: the
        terms they scale are left out of its equations at trace time, which makes a
        simulation cheaper, and their derivatives are then zero. Models without
        such terms return themselves (the default). `held_at_zero(())` computes
        every term again. Refits hold the gains of the effects they leave off."""
        return self

    def default_bounds(self, scales: DataScales, *, gauge: bool = True) -> "SearchBox":
        """The default search box for a record with these `scales` (what
        `ParameterSpace.default` searches). `gauge=True` fixes the parameters that
        only rescale an internal variable, where the model has such a symmetry."""
        name = type(self).__name__
        raise TypeError(
            f"{name}.default_bounds: no default bounds for {name}; build "
            "ParameterSpace(template, bounds) yourself."
        )

    def bouc_wen_shape(self) -> BoucWenShape:
        """The Bouc-Wen shape parameters (A, beta, gamma, n, D) of the hysteresis
        law, for Table 2's stability classes (`bibo_stability`)."""
        raise TypeError(
            f"{type(self).__name__} has no Bouc-Wen shape parameters (A, beta, gamma, "
            "n); pass a BoucWen-family model, or define bouc_wen_shape() on it."
        )

    def default_solver(self, recording: Recording) -> "RK4":
        """The solver `jaxhyst fit`, `evaluate` and `compensate` simulate this model
        with on `recording` (`jh.default_solver`), so that a saved model is
        evaluated as it was fitted: one RK4 step per sample (the default) unless the
        model is stiff on the sample scale."""
        from .._simulate import RK4

        return RK4()

    # What makes the output lag the drive (`jh.compensate`). They need concrete
    # parameter values (call them outside `jit`).

    def lag_reason(self) -> str | None:
        """Why the output lags the drive, so that the model has no per-sample inverse
        (a clause for a message: "... the drive cannot be found sample by sample"),
        or None (the default: the output responds to the present drive)."""
        return None

    def time_shift(self) -> float:
        """How far in time (s) the hysteresis reads the drive (its phi); 0.0 (the
        default) for a model that reads the present drive."""
        return 0.0

    def stage_dynamics(self) -> StageDynamics | None:
        """The second-order stage the output is seen through after the quasi-static
        response, or None (the default: no stage)."""
        return None

    def quasi_static(self) -> "AbstractHysteresisModel":
        """The model without what makes its output lag the drive (stage dynamics, a
        time shift): what the per-sample inversion can invert. The model itself (the
        default) where nothing lags."""
        return self

    # Exports.

    def c_export_parameters(self) -> dict[str, float]:
        """The constants `export_c` writes (k1, k2, A1, beta1, gamma1, n, eps of
        y = k1*u + k2*h, hdot = (A1 - (beta1*sgn(udot)*sgn(h) + gamma1)*|h|^n)*udot
        + eps*u*sgn(udot)). The default refuses: the model has no C export."""
        raise ValueError(
            f"export_c: {type(self).__name__} has no C export; PiezoBoucWen and "
            "CorrectedPiezoBoucWen (phi = 0) do."
        )

    def opensees_model(self) -> "StructuralBoucWen":
        """The model as OpenSees's Bouc-Wen materials read it (`opensees_material`):
        a `StructuralBoucWen` with the same restoring force. The default refuses:
        OpenSees has no material for the model (`has_opensees_material`)."""
        raise TypeError(
            "opensees_material: model must be a StructuralBoucWen or BoucWen (the "
            f"models OpenSees has a material for), got {type(self).__name__}."
        )

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


def _float_bounds(
    bounds: dict[str, tuple[float, float]],
) -> dict[str, tuple[float, float]]:
    return {name: (float(lo), float(hi)) for name, (lo, hi) in bounds.items()}


def held_gains_field():
    """The `zero_gains` field of an `AbstractGainHoldingModel` (static, empty by
    default, keyword-only)."""
    return eqx.field(static=True, default=frozenset(), kw_only=True)


class AbstractGainHoldingModel(AbstractHysteresisModel[DriveT]):
    """A model with effect terms it can leave out of its equations at trace time:
    the gains in `zero_gains` (static; empty by default) are held at zero, and the
    equations skip what they scale (`_holds`). Refits hold the gains of the effects
    they leave off, which makes every simulation of the refit cheaper."""

    if TYPE_CHECKING:
        zero_gains: ClassVar[frozenset[str]]
    else:
        zero_gains: eqx.AbstractVar[frozenset[str]]
    # The held gains are a way of computing, not part of the model (a model file
    # does not list them; a loaded model holds nothing).
    unlisted_fields: ClassVar[tuple[str, ...]] = ("smoothing", "zero_gains")

    def held_at_zero(self, names: Collection[str]) -> Self:
        """This model with the gains `names` held at zero (see
        `AbstractHysteresisModel.held_at_zero`). Each must be a parameter whose
        value is 0 already (needs concrete values: call it outside `jit`)."""
        names = frozenset(names)
        name = type(self).__name__
        unknown = sorted(names - set(self.parameter_names))
        if unknown:
            raise ValueError(
                f"{name}.held_at_zero: unknown parameter(s) {unknown}; this model "
                f"has {list(self.parameter_names)}."
            )
        nonzero = sorted(n for n in names if float(getattr(self, n)) != 0.0)
        if nonzero:
            raise ValueError(
                f"{name}.held_at_zero: {nonzero} are not zero; set them to 0 first "
                "(model.replace(...)), or hold only the zero ones."
            )
        return dataclasses.replace(self, zero_gains=names)

    def replace(self, **values: ArrayLike) -> Self:
        """A copy with some parameters replaced; a held gain that is set is released
        (its terms are computed again)."""
        replaced = super().replace(**values)
        released = replaced.zero_gains - set(values)
        if released == replaced.zero_gains:
            return replaced
        return dataclasses.replace(replaced, zero_gains=released)

    def _gain(self, name: str):
        """The gain `name`, or a literal 0 where it is held (nothing then depends on
        it): for terms cheap enough to compute either way."""
        return 0.0 if name in self.zero_gains else getattr(self, name)

    def _holds(self, *names: str) -> bool:
        """Whether every one of `names` is held at zero (its terms left out)."""
        return all(name in self.zero_gains for name in names)


class SearchBox(eqx.Module):
    """A model's default search box: `template` (the model with the gauge fixed,
    e.g. the piezo models' A1 = 1/max|u|), `bounds` of the free parameters in the
    model's units, and the free parameters searched on a log scale. `ParameterSpace`
    is built from it by `ParameterSpace.default`."""

    template: AbstractHysteresisModel
    bounds: dict[str, tuple[float, float]] = eqx.field(converter=_float_bounds)
    log_scale: tuple[str, ...] = eqx.field(converter=tuple, static=True, default=())


def legendre_drift(s, trend, curvature, *higher):
    """A slow drift in Legendre terms of the time s scaled to [-1, 1]:
    trend*s + curvature*(s^2 - 1/3) + sum_k higher[k]*P_{k+3}(s) (`higher` the
    coefficients of degree 3, 4, ...; curvature's s^2 - 1/3 is 2/3 P2). Zero when
    every coefficient is. The extended models' drift effects add it to their
    output."""
    total = trend * s + curvature * (s**2 - 1.0 / 3.0)
    previous, current = s, (3 * s**2 - 1) / 2  # P1, P2
    for degree, coefficient in enumerate(higher, start=2):
        # Bonnet: (k + 1) P_{k+1} = (2k + 1) s P_k - k P_{k-1}.
        previous, current = (
            current,
            ((2 * degree + 1) * s * current - degree * previous) / (degree + 1),
        )
        total = total + coefficient * current
    return total


def spline_drift(s, coefficients):
    """A slow drift as a uniform cubic B-spline in the time s scaled to [-1, 1]:
    k = len(coefficients) + 1 equal intervals carry k + 3 B-splines, of which the
    first is left out (the constant they sum to belongs to the model's own offset,
    so the rest span every such spline with it); `coefficients` are the others',
    in time order. Zero when every coefficient is. Each coefficient moves the
    drift only within four intervals of its knot: a refit follows a zero that
    wanders at the scale of one interval without swinging elsewhere."""
    coefficients = jnp.stack([jnp.asarray(c) for c in coefficients])
    full = jnp.concatenate([jnp.zeros(1, coefficients.dtype), coefficients])
    intervals = full.shape[0] - 3
    position = (jnp.asarray(s) + 1.0) / 2.0 * intervals
    index = jnp.clip(jnp.floor(position), 0, intervals - 1).astype(jnp.int32)
    u = jnp.clip(position - index, 0.0, 1.0)
    weights = (
        (1 - u) ** 3 / 6,
        (3 * u**3 - 6 * u**2 + 4) / 6,
        (-3 * u**3 + 3 * u**2 + 3 * u + 1) / 6,
        u**3 / 6,
    )
    return sum(w * full[index + k] for k, w in enumerate(weights))


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
