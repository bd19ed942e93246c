"""The sampled input u(t) as a continuous path that simulators and models can query.

Between samples the input is interpolated. `LinearInterpolation` (the default) makes
u piecewise linear with a constant udot on each sample interval: the rate-independent
Bouc-Wen operator then sees exactly the sampled turning points, and an RK4 step that
stays inside one interval integrates a smooth vector field (so it keeps its 4th order).
`CubicInterpolation` gives a C1 path (continuous udot) for band-limited inputs such as
multisines, where a piecewise-linear input under-represents the signal between samples.
"""

import abc
import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, Int


class AbstractInterpolation(eqx.Module):
    """How the input is reconstructed between samples."""

    @abc.abstractmethod
    def on_interval(
        self,
        values: Float[Array, " n"],
        dt: Float[ArrayLike, ""],
        interval: Int[ArrayLike, "..."],
        frac: Float[ArrayLike, "..."],
    ) -> tuple[Float[Array, "..."], Float[Array, "..."]]:
        """(u, du/dt) at fraction `frac` in [0, 1] of sample interval `interval`."""


class LinearInterpolation(AbstractInterpolation):
    """Piecewise-linear input, constant rate on each sample interval. The default:
    change it only for smooth, band-limited inputs sampled close to their bandwidth."""

    def on_interval(self, values, dt, interval, frac):
        left = values[interval]
        slope = (values[interval + 1] - left) / dt
        return left + frac * dt * slope, slope * jnp.ones_like(frac)


class CubicInterpolation(AbstractInterpolation):
    """Cubic Hermite (Catmull-Rom) input with central-difference slopes: C1 in time."""

    def on_interval(self, values, dt, interval, frac):
        n = values.shape[0]
        interval = jnp.asarray(interval)
        p0 = values[interval]
        p1 = values[interval + 1]
        before = values[jnp.maximum(interval - 1, 0)]
        after = values[jnp.minimum(interval + 2, n - 1)]
        # One-sided differences at the ends keep the path inside the data range.
        m0 = jnp.where(interval > 0, (p1 - before) / 2, p1 - p0)
        m1 = jnp.where(interval + 2 < n, (after - p0) / 2, p1 - p0)
        s = jnp.asarray(frac)
        s2 = s * s
        s3 = s2 * s
        value = (
            (2 * s3 - 3 * s2 + 1) * p0
            + (s3 - 2 * s2 + s) * m0
            + (-2 * s3 + 3 * s2) * p1
            + (s3 - s2) * m1
        )
        slope = (
            (6 * s2 - 6 * s) * p0
            + (3 * s2 - 4 * s + 1) * m0
            + (-6 * s2 + 6 * s) * p1
            + (3 * s2 - 2 * s) * m1
        ) / dt
        return value, slope


class InputPath(eqx.Module):
    """A uniformly sampled input u(t0 + k*dt) = values[k], interpolated between samples.

    Outside [t0, t0 + (n-1)*dt] the path holds its end value with zero rate.
    Build one from arrays with `InputPath.from_samples(t, u)`, which checks the time axis.

    `channels` holds further inputs sampled on the same grid, one row each (an MR
    damper's command voltage beside its displacement), for models that read more
    than one input (`model.input_names`); None for a single input. `values` is
    always the first (mechanical) input.
    """

    t0: Float[Array, ""]
    dt: Float[Array, ""]
    values: Float[Array, " n"]
    interpolation: AbstractInterpolation = eqx.field(
        default_factory=LinearInterpolation
    )
    channels: Float[Array, "k n"] | None = None

    def __init__(
        self,
        t0: Float[ArrayLike, ""],
        dt: Float[ArrayLike, ""],
        values: Float[ArrayLike, " n"],
        *,
        interpolation: AbstractInterpolation | None = None,
        channels: Float[ArrayLike, "k n"] | None = None,
    ):
        values = jnp.asarray(values)
        if values.ndim != 1:
            raise ValueError(
                f"InputPath: values must be one-dimensional, got shape {values.shape}; "
                "pass one input channel as a 1-D array."
            )
        if values.shape[0] < 2:
            raise ValueError(
                f"InputPath: need at least 2 samples, got {values.shape[0]}."
            )
        if not jnp.issubdtype(values.dtype, jnp.floating):
            values = values.astype(jnp.result_type(float))
        if isinstance(dt, (int, float)) and not dt > 0:
            raise ValueError(f"InputPath: dt must be positive, got {dt}.")
        self.t0 = jnp.asarray(t0, values.dtype)
        self.dt = jnp.asarray(dt, values.dtype)
        self.values = values
        self.interpolation = (
            LinearInterpolation() if interpolation is None else interpolation
        )
        if channels is None:
            self.channels = None
        else:
            channels = jnp.asarray(channels, values.dtype)
            if channels.ndim != 2 or channels.shape[1] != values.shape[0]:
                raise ValueError(
                    f"InputPath: channels must have shape (k, {values.shape[0]}) (one "
                    f"row per further input, as many samples as values), got "
                    f"{channels.shape}."
                )
            self.channels = channels

    @classmethod
    def from_samples(
        cls,
        t: Float[ArrayLike, " n"],
        u: Float[ArrayLike, " n"],
        *,
        interpolation: AbstractInterpolation | None = None,
        channels: Float[ArrayLike, "k n"] | None = None,
        rtol: float = 1e-6,
    ) -> "InputPath":
        """Build a path from sample times and values (and further input `channels`,
        one row each); `t` must be uniformly spaced (within `rtol` of the mean step).
        Resample first if it is not."""
        t_np = np.asarray(t, dtype=float)
        u_arr = jnp.asarray(u)
        if t_np.ndim != 1 or u_arr.ndim != 1 or t_np.shape != u_arr.shape:
            raise ValueError(
                f"InputPath.from_samples: t and u must be 1-D of equal length, got "
                f"shapes {t_np.shape} and {tuple(u_arr.shape)}."
            )
        if t_np.shape[0] < 2:
            raise ValueError("InputPath.from_samples: need at least 2 samples.")
        steps = np.diff(t_np)
        if np.any(steps <= 0):
            raise ValueError(
                "InputPath.from_samples: time must be strictly increasing; sort the "
                "samples or drop duplicates."
            )
        mean_step = (t_np[-1] - t_np[0]) / (t_np.shape[0] - 1)
        if np.max(np.abs(steps - mean_step)) > rtol * mean_step + 1e-12:
            raise ValueError(
                "InputPath.from_samples: time is not uniformly sampled (step varies "
                f"from {steps.min():.6g} to {steps.max():.6g}); resample onto a "
                "uniform grid first (Recording.resample)."
            )
        return cls(
            t_np[0], mean_step, u_arr, interpolation=interpolation, channels=channels
        )

    @property
    def num_samples(self) -> int:
        return self.values.shape[0]

    @property
    def num_inputs(self) -> int:
        """How many inputs the path carries (1 + the rows of `channels`)."""
        return 1 + (0 if self.channels is None else self.channels.shape[-2])

    def channels_on_interval(
        self, interval: Int[ArrayLike, ""], frac: Float[ArrayLike, ""]
    ) -> tuple[Float[Array, " k"], Float[Array, " k"]]:
        """The further inputs and their rates at fraction `frac` of sample interval
        `interval`, interpolated like `values`."""
        if self.channels is None:
            raise ValueError(
                "InputPath.channels_on_interval: this path carries one input; build "
                "it with channels=... (or a Recording with more inputs)."
            )
        return jax.vmap(
            lambda row: self.interpolation.on_interval(row, self.dt, interval, frac)
        )(self.channels)

    def channels_at(
        self, t: Float[ArrayLike, ""]
    ) -> tuple[Float[Array, " k"], Float[Array, " k"]]:
        """The further inputs and their rates at time `t` (held outside the
        record, like `evaluate`)."""
        position = (jnp.asarray(t, self.dt.dtype) - self.t0) / self.dt
        last = self.num_samples - 1
        interval = jnp.clip(jnp.floor(position), 0, last - 1).astype(jnp.int32)
        inside = (position >= 0) & (position <= last)
        values, rates = self.channels_on_interval(
            interval, jnp.clip(position - interval, 0, 1)
        )
        return values, jnp.where(inside, rates, 0)

    @property
    def times(self) -> Float[Array, " n"]:
        return self.t0 + self.dt * jnp.arange(self.num_samples, dtype=self.dt.dtype)

    @property
    def t1(self) -> Float[Array, ""]:
        return self.t0 + self.dt * (self.num_samples - 1)

    def on_interval(
        self, interval: Int[ArrayLike, "..."], frac: Float[ArrayLike, "..."]
    ) -> tuple[Float[Array, "..."], Float[Array, "..."]]:
        """(u, udot) at fraction `frac` of sample interval `interval` (no clamping)."""
        return self.interpolation.on_interval(self.values, self.dt, interval, frac)

    def on_interval_shifted(
        self,
        interval: Int[ArrayLike, ""],
        frac: Float[ArrayLike, ""],
        shift: Float[ArrayLike, ""],
    ) -> tuple[Float[Array, ""], Float[Array, ""]]:
        """(u, udot) at time `shift` after the point `frac` of `interval`.

        With linear interpolation the shifted input is the piecewise-linear path
        through the shifted samples u(t_k + shift): on each interval its rate is the
        secant between the interval's two shifted ends. The simulated output is then
        continuous in `shift` (reading point rates at RK4 stages would move in
        half-sample stairs as kinks cross the stage points) and a zero shift is
        `on_interval` exactly. Otherwise (cubic): the shifted point stays on the same interval whenever it can (so a zero shift
        reproduces `on_interval` exactly, one-sided rate included); outside the record
        the path holds its end value with zero rate. Differentiable in `shift`: the
        rate's derivative is the input's curvature, smoothed over neighbouring samples
        (a piecewise-linear path has kinks, whose exact derivative would be zero almost
        everywhere and blind a gradient-based fit of the shift).
        """
        if isinstance(self.interpolation, LinearInterpolation):
            return _shifted_secant(self.values, self.dt, interval, frac, shift)
        return _shifted_read(
            self.interpolation, self.values, self.dt, interval, frac, shift
        )

    def evaluate(
        self, t: Float[ArrayLike, "..."]
    ) -> tuple[Float[Array, "..."], Float[Array, "..."]]:
        """(u, udot) at times `t` (any shape). Right-continuous in udot at samples."""
        position = (jnp.asarray(t, self.dt.dtype) - self.t0) / self.dt
        last = self.num_samples - 1
        interval = jnp.clip(jnp.floor(position), 0, last - 1).astype(jnp.int32)
        frac = position - interval
        inside = (position >= 0) & (position <= last)
        u, udot = self.on_interval(interval, jnp.clip(frac, 0, 1))
        return u, jnp.where(inside, udot, 0)


def _value_at(values, position):
    """The piecewise-linear path through `values` at fractional sample `position`,
    holding the end values outside the record."""
    last = values.shape[0] - 1
    position = jnp.clip(position, 0, last)
    index = jnp.clip(jnp.floor(position), 0, last - 1).astype(jnp.int32)
    weight = position - index
    return values[index] + weight * (values[index + 1] - values[index])


def _shifted_secant(values, dt, interval, frac, shift):
    offset = shift / dt
    left = _value_at(values, interval + offset)
    right = _value_at(values, interval + 1 + offset)
    slope = (right - left) / dt
    return left + frac * dt * slope, slope * jnp.ones_like(frac)


def _shifted_position(values, dt, interval, frac, shift):
    offset = shift / dt
    whole = jnp.floor(offset)
    target = interval + whole.astype(jnp.int32)
    target_frac = frac + (offset - whole)
    spill = target_frac > 1
    target = jnp.where(spill, target + 1, target)
    target_frac = jnp.where(spill, target_frac - 1, target_frac)
    last = values.shape[0] - 1
    inside = (target >= 0) & (target <= last - 1)
    clamped = jnp.clip(target, 0, last - 1)
    frac_in = jnp.where(target < 0, 0.0, jnp.where(target > last - 1, 1.0, target_frac))
    return clamped, frac_in.astype(values.dtype), inside


@functools.partial(jax.custom_jvp, nondiff_argnums=(0,))
def _shifted_read(interpolation, values, dt, interval, frac, shift):
    index, where, inside = _shifted_position(values, dt, interval, frac, shift)
    u, udot = interpolation.on_interval(values, dt, index, where)
    return u, jnp.where(inside, udot, 0)


@_shifted_read.defjvp
def _shifted_read_jvp(interpolation, primals, tangents):
    values, dt, interval, frac, shift = primals
    d_values, _, _, d_frac, d_shift = tangents
    u, udot = _shifted_read(interpolation, values, dt, interval, frac, shift)
    index, where, inside = _shifted_position(values, dt, interval, frac, shift)
    # Linear in the values: their tangent goes through the same read.
    du_v, dudot_v = _shifted_read(interpolation, d_values, dt, interval, frac, shift)
    n = values.shape[0]

    def curvature(j):
        j = jnp.clip(j, 1, n - 2)
        return (values[j + 1] - 2 * values[j] + values[j - 1]) / dt**2

    # Curvature at the two samples bounding the point, blended by position.
    second = (1 - where) * curvature(index) + where * curvature(index + 1)
    second = jnp.where(inside, second, 0)
    d_time = d_shift + d_frac * dt
    return (u, udot), (du_v + udot * d_time, dudot_v + second * d_time)
