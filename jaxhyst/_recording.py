"""A measured (or simulated) input/output record: time `t`, input `u`, output `y`.

`Recording` checks its data once, when it is built, so that everything downstream can
assume a finite, strictly increasing, uniformly sampled record with a non-constant
input. Every problem is reported as a `RecordingError` whose one-line message names
the problem and the fix.
"""

import csv
import math
import os
import re
import zipfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import equinox as eqx
import numpy as np
from jaxtyping import ArrayLike, Float, Int

from ._files import Refusal, refuse_existing
from ._inputs import AbstractInterpolation, InputPath


class RecordingError(ValueError):
    """A recording (or the file it is read from) cannot be used as it is. The message
    says what is wrong and how to fix it.

    Besides the message, the error carries what the command line needs to say it in
    its own words: `owner`, the function or recording the message is prefixed with
    ("Recording.load", "Recording 'x'"; None: none), `problem`, the message without
    that prefix, and `cli`, the message as the command line says it where the fix
    differs (flags instead of Python arguments; None: `problem` says it); `kind`
    names a class of problem where a caller may act on it ("constant", "scale";
    None: any other), and `recording` the name of the recording the error is about
    where its `cli` does not name it (the command line names its file)."""

    owner: str | None
    problem: str
    cli: str | None
    kind: str | None
    recording: str | None

    def __init__(
        self,
        problem: str,
        *,
        owner: str | None = None,
        cli: str | None = None,
        kind: str | None = None,
        recording: str | None = None,
    ):
        super().__init__(f"{owner}: {problem}" if owner else problem)
        self.owner = owner
        self.problem = problem
        self.cli = cli
        self.kind = kind
        self.recording = recording

    @property
    def cli_message(self) -> str:
        """The message in the command line's words."""
        return self.problem if self.cli is None else self.cli


class _FileNotFound(FileNotFoundError):
    """A `FileNotFoundError` with the message in the command line's words as well
    (`cli_message`, as a `RecordingError` has)."""

    cli_message: str


# The sample times may jitter around a uniform grid (CSV time stamps such as
# 0.000200010001 do); deviations up to this fraction of the step are accepted.
_UNIFORM_RTOL = 1e-3
_META_PREFIX = "jaxhyst_"
_MAT_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,62}")
_UNIT_SUFFIX = re.compile(r"^(.*?)\s*\[([^\[\]]*)\]$")


def _as_column(label: str, values, where: str) -> np.ndarray:
    if np.iscomplexobj(values):
        raise RecordingError(
            f"{label} is complex; pass its real part (np.real) or magnitude.",
            owner=where,
        )
    try:
        column = np.array(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise RecordingError(
            f"{label} is not numeric; pass an array of numbers.",
            owner=where,
        ) from None
    if column.ndim != 1:
        raise RecordingError(
            f"{label} must be one-dimensional, got shape {column.shape}; "
            "pass a single channel, flattened with np.ravel.",
            owner=where,
        )
    return column


class Recording(eqx.Module):
    """A uniformly sampled record of input `u` and output `y` at times `t`.

    Build one from arrays, `Recording(t, u, y, name=...)`, or from a file,
    `Recording.load(path)`. The constructor raises `RecordingError` unless the three
    columns are 1-D and of equal length (at least 2 samples), finite, with `t` strictly
    increasing and uniformly sampled (deviations up to 1e-3 of the step are accepted;
    pass `resample=True` to interpolate a non-uniform record onto a uniform grid), and
    `u` not constant. Arrays are stored as read-only float64 NumPy arrays.

    A recording may carry further inputs beside `u` (an MR damper's command voltage
    beside its displacement): `more_inputs={"v": values}` (names as keys, in order)
    with `more_input_units={"v": "V"}`; they are checked like `u`, kept by every
    method that cuts or resamples the record, saved and loaded, and passed to the
    simulation as `input_path().channels`. `u` stays the first (mechanical) input.
    """

    t: Float[np.ndarray, " n"]
    u: Float[np.ndarray, " n"]
    y: Float[np.ndarray, " n"]
    # Metadata is static, so a Recording can be passed through `jax.jit`.
    name: str = eqx.field(static=True)
    input_name: str = eqx.field(static=True)
    output_name: str = eqx.field(static=True)
    input_unit: str = eqx.field(static=True)
    output_unit: str = eqx.field(static=True)
    time_unit: str = eqx.field(static=True)
    # Further inputs, one row each (shape (0, n) for one input), and their names and
    # units.
    more_inputs: Float[np.ndarray, "k n"]
    more_input_names: tuple[str, ...] = eqx.field(static=True)
    more_input_units: tuple[str, ...] = eqx.field(static=True)

    def __init__(
        self,
        t: Float[ArrayLike, " n"],
        u: Float[ArrayLike, " n"],
        y: Float[ArrayLike, " n"],
        *,
        name: str = "recording",
        input_name: str = "u",
        output_name: str = "y",
        input_unit: str = "",
        output_unit: str = "",
        time_unit: str = "s",
        resample: bool = False,
        more_inputs: Mapping[str, Float[ArrayLike, " n"]] | None = None,
        more_input_units: Mapping[str, str] | None = None,
    ):
        more_inputs = {} if more_inputs is None else dict(more_inputs)
        more_input_units = {} if more_input_units is None else dict(more_input_units)
        for option, value in (
            ("name", name),
            ("input_name", input_name),
            ("output_name", output_name),
            ("input_unit", input_unit),
            ("output_unit", output_unit),
            ("time_unit", time_unit),
        ):
            if not isinstance(value, str):
                raise TypeError(
                    f"Recording: {option} must be a string, got {type(value).__name__}."
                )
        where = f"Recording {name!r}"
        for key in (*more_inputs, *more_input_units):
            if not isinstance(key, str) or not key:
                raise TypeError(
                    f"{where}: more_inputs and more_input_units are keyed by input "
                    f"names (non-empty strings), got {key!r}."
                )
        unknown = set(more_input_units) - set(more_inputs)
        if unknown:
            raise RecordingError(
                f"more_input_units names {sorted(unknown)}, which are not "
                f"among more_inputs {list(more_inputs)}; key the units by the same "
                "names.",
                owner=where,
            )
        clash = set(more_inputs) & {input_name, output_name}
        if clash:
            raise RecordingError(
                f"further inputs {sorted(clash)} share a name with the input "
                f"{input_name!r} or the output {output_name!r}; rename them.",
                owner=where,
            )
        labels = (
            "time 't'",
            f"input {input_name!r}",
            f"output {output_name!r}",
            *(f"input {key!r}" for key in more_inputs),
        )
        t = _as_column(labels[0], t, where)
        u = _as_column(labels[1], u, where)
        y = _as_column(labels[2], y, where)
        more = [
            _as_column(label, values, where)
            for label, values in zip(labels[3:], more_inputs.values())
        ]
        lengths = [c.shape[0] for c in (t, u, y, *more)]
        if len(set(lengths)) > 1:
            counted = ", ".join(
                f"{label} has {count}" for label, count in zip(labels, lengths)
            )
            raise RecordingError(
                f"length mismatch, {counted} samples; pass columns of equal "
                "length, one value per time stamp.",
                owner=where,
            )
        n = t.shape[0]
        if n < 2:
            raise RecordingError(
                f"has {n} sample(s); a recording needs at least 2.",
                owner=where,
            )
        for label, column in zip(labels, (t, u, y, *more), strict=True):
            bad = ~np.isfinite(column)
            if bad.any():
                row = int(np.argmax(bad))
                raise RecordingError(
                    f"{label} has {int(bad.sum())} NaN/inf value(s), the "
                    f"first at row {row} (t = {t[row]:.6g}); drop those rows or "
                    "interpolate over them before building the recording.",
                    owner=where,
                    cli=f"{label} has {int(bad.sum())} NaN/inf value(s), the first at "
                    f"row {row} (t = {t[row]:.6g}); drop those rows from the file, or "
                    "interpolate over them.",
                )
        steps = np.diff(t)
        if np.any(steps <= 0):
            i = int(np.argmax(steps <= 0)) + 1
            raise RecordingError(
                f"time is not strictly increasing at row {i} "
                f"(t[{i}] = {t[i]:.9g} <= t[{i - 1}] = {t[i - 1]:.9g}); sort the "
                "samples by time and drop duplicated time stamps.",
                owner=where,
            )
        mean_step = (t[-1] - t[0]) / (n - 1)
        if np.max(np.abs(steps - mean_step)) > _UNIFORM_RTOL * mean_step:
            if not resample:
                raise RecordingError(
                    f"time is not uniformly sampled (step varies from "
                    f"{steps.min():.6g} to {steps.max():.6g}); pass resample=True to "
                    "interpolate linearly onto a uniform grid with the mean step, or "
                    "resample it yourself.",
                    owner=where,
                    cli=f"time is not uniformly sampled (step varies from "
                    f"{steps.min():.6g} to {steps.max():.6g}); resample the record onto "
                    "a uniform grid first (the command line reads uniformly sampled "
                    "records), or pick --start/--end around a uniform part.",
                )
            grid = np.asarray(t[0] + mean_step * np.arange(n), dtype=np.float64)
            grid[-1] = t[-1]
            u = np.asarray(np.interp(grid, t, u))
            y = np.asarray(np.interp(grid, t, y))
            more = [np.asarray(np.interp(grid, t, c)) for c in more]
            t = grid
        if np.ptp(u) == 0:
            raise RecordingError(
                f"input {input_name!r} is constant ({u[0]:.6g}) over the "
                "whole record, so nothing excites the hysteresis; pick a segment "
                "where the input varies, or check the column selection.",
                owner=where,
                cli=f"input {input_name!r} is constant ({u[0]:.6g}) over the whole "
                "record, so nothing excites the hysteresis; check --input, or pick "
                "--start/--end where the input varies.",
            )
        stacked = np.stack(more) if more else np.zeros((0, n), np.float64)
        for column in (t, u, y, stacked):
            column.setflags(write=False)
        self.t = t
        self.u = u
        self.y = y
        self.more_inputs = stacked
        self.more_input_names = tuple(more_inputs)
        self.more_input_units = tuple(more_input_units.get(k, "") for k in more_inputs)
        self.name = name
        self.input_name = input_name
        self.output_name = output_name
        self.input_unit = input_unit
        self.output_unit = output_unit
        self.time_unit = time_unit

    @classmethod
    def quasi_static(
        cls,
        displacement: Float[ArrayLike, " n"],
        force: Float[ArrayLike, " n"],
        *,
        name: str = "recording",
        pseudo_dt: float = 1.0,
        input_name: str = "displacement",
        output_name: str = "force",
        input_unit: str = "",
        output_unit: str = "",
    ) -> "Recording":
        """A quasi-static test without a time axis: imposed `displacement` (the
        input `u`) and measured restoring `force` (the output `y`), one pair per
        sample.

        The time is a pseudo time t = k * pseudo_dt, k the sample index, labelled
        `time_unit` "sample" when pseudo_dt = 1 and "pseudo s" otherwise.
        Rate-independent models (Bouc-Wen and its degrading/pinching forms) give the
        same force for any pseudo_dt; only rate-dependent terms (damping, mass)
        would depend on it.
        """
        where = f"Recording {name!r}"
        try:
            pseudo_dt = float(pseudo_dt)
        except (TypeError, ValueError):
            raise RecordingError(
                f"pseudo_dt must be a number, got {pseudo_dt!r}.",
                owner=where,
            ) from None
        if not (math.isfinite(pseudo_dt) and pseudo_dt > 0):
            raise RecordingError(
                f"pseudo_dt must be positive and finite, got {pseudo_dt}.",
                owner=where,
            )
        u = _as_column(f"input {input_name!r}", displacement, where)
        y = _as_column(f"output {output_name!r}", force, where)
        if u.shape != y.shape:
            raise RecordingError(
                f"{input_name} has {u.shape[0]} samples but {output_name} "
                f"has {y.shape[0]}; pass one {output_name} value per {input_name} "
                "value (trim the longer one, or check the files).",
                owner=where,
            )
        return cls(
            pseudo_dt * np.arange(u.shape[0], dtype=np.float64),
            u,
            y,
            name=name,
            input_name=input_name,
            output_name=output_name,
            input_unit=input_unit,
            output_unit=output_unit,
            time_unit="sample" if pseudo_dt == 1.0 else "pseudo s",
        )

    # ------------------------------------------------------------------ properties

    @property
    def has_pseudo_time(self) -> bool:
        """Whether the time axis only orders the samples (`quasi_static` records,
        time unit "sample" or "pseudo s")."""
        return self.time_unit in ("sample", "pseudo s")

    @property
    def input_names(self) -> tuple[str, ...]:
        """Every input's name: `input_name`, then `more_input_names`."""
        return (self.input_name, *self.more_input_names)

    @property
    def num_inputs(self) -> int:
        """How many inputs the recording carries (1 + the further inputs)."""
        return 1 + len(self.more_input_names)

    def more_input(self, name: str) -> Float[np.ndarray, " n"]:
        """The further input called `name`."""
        if name not in self.more_input_names:
            raise KeyError(
                f"Recording {self.name!r} has no further input {name!r}; its inputs "
                f"are {self.input_names}."
            )
        return self.more_inputs[self.more_input_names.index(name)]

    @property
    def num_samples(self) -> int:
        """Number of samples."""
        return int(self.t.shape[0])

    @property
    def dt(self) -> float:
        """Sample step: the mean step (t[-1] - t[0]) / (num_samples - 1)."""
        return float((self.t[-1] - self.t[0]) / (self.num_samples - 1))

    @property
    def sample_rate(self) -> float:
        """Samples per unit time, 1 / dt."""
        return 1.0 / self.dt

    @property
    def duration(self) -> float:
        """t[-1] - t[0]."""
        return float(self.t[-1] - self.t[0])

    # --------------------------------------------------------------------- methods

    def _replace(
        self, t, u, y, more=None, *, more_names=None, more_units=None
    ) -> "Recording":
        """A recording with new columns and this one's names and units; `more`: the
        further inputs (one row each), as many rows as this one has (None: keep
        them, for the same samples), unless `more_names`/`more_units` name others."""
        more = self.more_inputs if more is None else more
        names = self.more_input_names if more_names is None else more_names
        units = self.more_input_units if more_units is None else more_units
        return Recording(
            t,
            u,
            y,
            name=self.name,
            input_name=self.input_name,
            output_name=self.output_name,
            input_unit=self.input_unit,
            output_unit=self.output_unit,
            time_unit=self.time_unit,
            more_inputs=dict(zip(names, more, strict=True)),
            more_input_units=dict(zip(names, units, strict=True)),
        )

    def _rows(self, keep) -> "Recording":
        """The samples `keep` (a mask or slice) as a new recording."""
        return self._replace(
            self.t[keep], self.u[keep], self.y[keep], self.more_inputs[:, keep]
        )

    def input_path(
        self, *, interpolation: AbstractInterpolation | None = None
    ) -> InputPath:
        """The input as an `InputPath` on the uniform grid t[0] + k*dt (the further
        inputs as its `channels`)."""
        channels = self.more_inputs if self.more_input_names else None
        return InputPath(
            self.t[0],
            self.dt,
            self.u,
            interpolation=interpolation,
            channels=channels,
        )

    def with_output(self, y: Float[ArrayLike, " n"]) -> "Recording":
        """A copy with the output replaced by `y` (e.g. a simulated output)."""
        return self._replace(self.t, self.u, y)

    def with_input(
        self, name: str, values: float | Float[ArrayLike, " n"], *, unit: str = ""
    ) -> "Recording":
        """A copy with one more input `name` after the others: `values` per sample,
        or one number for an input held constant through the test (a damper tested
        at one coil current: `rec.with_input("command", 1.5, unit="V")`). Raises
        `RecordingError` if the name is taken or the length differs."""
        if name in (self.input_name, self.output_name, *self.more_input_names):
            raise RecordingError(
                f"{self.name!r} already has a column named "
                f"{name!r}; pick another name.",
                owner="Recording.with_input",
            )
        column = np.asarray(values, dtype=np.float64)
        if column.ndim == 0:
            column = np.full(self.num_samples, float(column))
        return self._replace(
            self.t,
            self.u,
            self.y,
            [*self.more_inputs, column],
            more_names=(*self.more_input_names, name),
            more_units=(*self.more_input_units, unit),
        )

    @classmethod
    def join(
        cls, recordings: Sequence["Recording"], *, mixed_rates: bool = False
    ) -> "Recording":
        """Several recordings' samples one after another, as one recording named
        "a + b + ...": the time continues across each join at the first recording's
        step. They must share their units and sample rate. Used to read several
        tests of one specimen as one vector (`diagnose` does); the joined record is
        not one experiment, so do not simulate across the joins.

        `mixed_rates=True` also joins recordings at different sample rates, none
        resampled: every sample is kept and the joined time runs at the finest
        recording's step, so a recording at a lower rate runs faster in it than it
        was recorded (a 200 samples/s test beside a 1 kHz one lasts a fifth of its
        length). Its time axis and rates are then those of the vector, not of the
        experiments: read it sample by sample (display, masks, residuals), and
        simulate each recording on its own path."""
        recordings = list(recordings)
        if not recordings or not all(isinstance(r, Recording) for r in recordings):
            raise TypeError("Recording.join: pass a non-empty list of Recordings.")
        first = recordings[0]
        expected = (
            first.input_unit,
            first.output_unit,
            first.time_unit,
            *first.more_input_units,
        )
        for other in recordings[1:]:
            if other.more_input_names != first.more_input_names:
                raise RecordingError(
                    f"{other.name!r} has inputs {other.input_names}, "
                    f"{first.name!r} has {first.input_names}; recordings read together "
                    "need the same further inputs.",
                    owner="Recording.join",
                )
            units = (
                other.input_unit,
                other.output_unit,
                other.time_unit,
                *other.more_input_units,
            )
            if units != expected:
                raise RecordingError(
                    f"{other.name!r} has units (input, output, time) "
                    f"{units}, {first.name!r} has {expected}; convert them to one set "
                    "of units.",
                    owner="Recording.join",
                )
            if not mixed_rates and abs(other.dt - first.dt) > _UNIFORM_RTOL * first.dt:
                raise RecordingError(
                    f"{other.name!r} is sampled at "
                    f"{other.sample_rate:.6g} per {other.time_unit}, {first.name!r} "
                    f"at {first.sample_rate:.6g}; recordings read together need one "
                    "sample rate, or join(..., mixed_rates=True) to read their samples "
                    "one after another (each kept at its own rate).",
                    owner="Recording.join",
                )
        if len(recordings) == 1:
            return first
        dt = first.dt
        if any(abs(r.dt - first.dt) > _UNIFORM_RTOL * first.dt for r in recordings):
            dt = min(r.dt for r in recordings)  # mixed_rates: the finest step
        times, start = [], float(first.t[0])
        for recording in recordings:
            times.append(start + dt * np.arange(recording.num_samples))
            start = float(times[-1][-1]) + dt
        return cls(
            np.concatenate(times),
            np.concatenate([r.u for r in recordings]),
            np.concatenate([r.y for r in recordings]),
            name=" + ".join(r.name for r in recordings),
            input_name=first.input_name,
            output_name=first.output_name,
            input_unit=first.input_unit,
            output_unit=first.output_unit,
            time_unit=first.time_unit,
            more_inputs={
                key: np.concatenate([r.more_input(key) for r in recordings])
                for key in first.more_input_names
            },
            more_input_units=dict(
                zip(first.more_input_names, first.more_input_units, strict=True)
            ),
        )

    def segment(self, start: float | None, stop: float | None) -> "Recording":
        """The samples with start <= t <= stop (None: from the beginning / to the
        end), as a new recording that keeps the original time stamps."""
        tol = _UNIFORM_RTOL * self.dt
        lo = self.t[0] if start is None else float(start)
        hi = self.t[-1] if stop is None else float(stop)
        if not lo < hi:
            raise RecordingError(
                f"segment({start}, {stop}) is empty; pass start < stop.",
                owner=f"Recording {self.name!r}",
            )
        keep = (self.t >= lo - tol) & (self.t <= hi + tol)
        count = int(keep.sum())
        if count < 2:
            spanning = (
                f"{count} sample(s) of a record spanning [{self.t[0]:.6g}, "
                f"{self.t[-1]:.6g}] {self.time_unit}; pick a window with at least 2 "
                "samples."
            )
            raise RecordingError(
                f"segment({start}, {stop}) holds {spanning}",
                owner=f"Recording {self.name!r}",
                cli=f"the window holds {spanning}",
            )
        return self._rows(keep)

    def split(self, fraction: float) -> tuple["Recording", "Recording"]:
        """Split at `fraction` (0 < fraction < 1) of the samples into (first,
        second), e.g. for estimation/validation. The parts do not overlap."""
        if not 0 < fraction < 1:
            raise RecordingError(
                f"split fraction must lie strictly between 0 and 1, got {fraction}.",
                owner=f"Recording {self.name!r}",
            )
        n = self.num_samples
        k = int(round(fraction * n))
        if k < 2 or n - k < 2:
            raise RecordingError(
                f"split({fraction}) of {n} samples leaves "
                f"{k} and {n - k} samples; each part needs at least 2, so pick a "
                "fraction nearer 0.5.",
                owner=f"Recording {self.name!r}",
            )
        return self._rows(slice(None, k)), self._rows(slice(k, None))

    def resample(self, dt: float) -> "Recording":
        """Linear interpolation onto the grid t[0] + k*dt that fits in the record.

        Use it to thin or refine a record; it does not low-pass filter, so filter
        first when reducing the rate of a signal with content above the new Nyquist
        frequency.
        """
        try:
            dt = float(dt)
        except (TypeError, ValueError):
            raise RecordingError(
                f"resample dt must be a number, got {dt!r}.",
                owner=f"Recording {self.name!r}",
            ) from None
        if not (math.isfinite(dt) and dt > 0):
            raise RecordingError(
                f"resample dt must be positive and finite, got {dt}.",
                owner=f"Recording {self.name!r}",
            )
        count = int(math.floor(self.duration / dt * (1 + 1e-12) + 1e-9)) + 1
        if count < 2:
            raise RecordingError(
                f"resample({dt}) leaves {count} sample(s) "
                f"in a record of duration {self.duration:.6g}; pass a smaller dt.",
                owner=f"Recording {self.name!r}",
            )
        grid = self.t[0] + dt * np.arange(count)
        grid = np.minimum(grid, self.t[-1])
        return self._replace(
            grid,
            np.interp(grid, self.t, self.u),
            np.interp(grid, self.t, self.y),
            [np.interp(grid, self.t, row) for row in self.more_inputs],
        )

    def reversals(self, *, tolerance: float = 0.01) -> Int[np.ndarray, " r"]:
        """The sample indices where the input `u` changes direction, in increasing
        order (interior turning points only: not the first or last sample).

        A turning-point detector with hysteresis: a running extremum counts as a
        reversal once the input has come back from it by more than `tolerance` times
        the input's range (max - min), so wiggles smaller than that (noise on a
        measured displacement) are ignored. Of a flat extremum the first sample is
        returned. Consecutive reversals bound half cycles, every second one whole
        cycles.
        """
        try:
            tolerance = float(tolerance)
        except (TypeError, ValueError):
            raise RecordingError(
                f"reversals tolerance must be a number, got {tolerance!r}.",
                owner=f"Recording {self.name!r}",
            ) from None
        if not 0 <= tolerance < 1:
            raise RecordingError(
                f"reversals tolerance must lie in [0, 1) "
                f"(a fraction of the input's range), got {tolerance}; 0.01 ignores "
                "wiggles below 1 % of the range.",
                owner=f"Recording {self.name!r}",
            )
        u = self.u
        threshold = tolerance * float(np.ptp(u))
        found: list[int] = []
        direction = 0  # +1 rising, -1 falling, 0 not yet known
        lo = hi = extremum = 0
        for k in range(1, u.shape[0]):
            value = u[k]
            if direction == 0:
                # Until the input has moved by the threshold, the start's wiggles
                # are not reversals; the first such move sets the direction.
                hi = k if value > u[hi] else hi
                lo = k if value < u[lo] else lo
                if value - u[lo] > threshold:
                    direction, extremum = 1, k
                elif u[hi] - value > threshold:
                    direction, extremum = -1, k
            elif direction > 0:
                if value > u[extremum]:
                    extremum = k
                elif u[extremum] - value > threshold:
                    found.append(extremum)
                    direction, extremum = -1, k
            else:
                if value < u[extremum]:
                    extremum = k
                elif value - u[extremum] > threshold:
                    found.append(extremum)
                    direction, extremum = 1, k
        return np.asarray(found, dtype=np.int64)

    def require_samples(self, minimum: int, *, what: str = "this model") -> None:
        """Raise `RecordingError` unless the record has at least `minimum` samples."""
        if self.num_samples < minimum:
            raise RecordingError(
                f"Recording {self.name!r} has {self.num_samples} samples; {what} "
                f"needs at least {minimum}; use a longer (or finer) recording.",
                cli=f"has {self.num_samples} samples; {what} needs at least "
                f"{minimum}; pass a longer recording (or one sampled at a higher "
                "rate).",
                recording=self.name,
            )

    # ------------------------------------------------------------------------- I/O

    @classmethod
    def load(
        cls,
        path: str | os.PathLike,
        *,
        time: str | int | None = "t",
        input: str | int | Sequence[str | int] | None = None,
        output: str | int | None = None,
        header: bool | None = None,
        resample: bool = False,
        name: str | None = None,
    ) -> "Recording":
        """Read a recording from `.csv`/`.txt`, `.npz` or `.mat`.

        `time`, `input` and `output` pick the columns (default "t", "u", "y"): by
        header name for text files with `header=True` (the default; a unit in
        brackets, as in "u [V]", may be left out of the name and becomes the unit),
        by 0-based column index (an int) for text files, and by key/variable name for
        `.npz`/`.mat` (arrays shaped (N,), (1, N) or (N, 1)). Text files may be comma,
        semicolon, tab or whitespace separated; empty columns (such as a leading
        index column) are fine if not selected. `resample=True` interpolates a
        non-uniform time axis onto a uniform grid with the mean step. `name` defaults
        to the name stored by `save`, else the stem.

        `input` may list several columns (`input=["u", "v"]`): the first is `u`, the
        others become `more_inputs` under their column names. None reads the inputs
        `save` wrote (all of them), else "u"; `output=None` likewise reads the output
        `save` wrote with several inputs, else "y".

        `time=None` reads a quasi-static test without a time column: a text file of
        exactly two equally long columns, displacement and force (default `input=0`,
        `output=1`, no header unless `header=True`), built with `quasi_static` (pseudo
        time t = sample index).
        """
        path = Path(path)
        if not path.is_file():
            reason = "is a directory" if path.is_dir() else "does not exist"
            error = _FileNotFound(
                f"Recording.load: {str(path)!r} {reason}; check the path."
            )
            error.cli_message = f"{str(path)!r} {reason}; check the path."
            raise error
        suffix = path.suffix.lower()
        if time is None:
            if input is not None and not isinstance(input, str | int):
                raise RecordingError(
                    "time=None reads two columns (displacement, "
                    f"force); pick one input column, got input={input!r}.",
                    owner="Recording.load",
                )
            return cls._load_quasi_static(path, input, output, bool(header), name)
        if isinstance(input, str | int) or input is None:
            inputs: list[str | int] | None = None if input is None else [input]
        else:
            inputs = list(input)
            if not inputs:
                raise RecordingError(
                    "input=[] selects no input; name at least one column.",
                    owner="Recording.load",
                )
        header = True if header is None else header
        if suffix not in (".csv", ".txt", ".npz", ".mat"):
            raise RecordingError(
                f"unknown file type {path.suffix!r} of {str(path)!r}; "
                "use .csv, .txt, .npz or .mat.",
                owner="Recording.load",
            )
        saved = _saved_inputs(path, suffix) if None in (input, output) else ()
        if inputs is None:
            inputs = list(saved) or ["u"]
        if output is None:
            output = (_saved_output(path, suffix, saved) if saved else None) or "y"
        selectors = (time, *inputs, output)
        if suffix in (".csv", ".txt"):
            columns, units = _read_text(path, selectors, header)
            stored: dict[str, str] = {}
        else:
            columns, units, stored = _read_arrays(path, selectors, suffix[1:])
        # Columns picked by index take the default names ("u", "u2", ..., "y").
        defaults = ("u", *(f"u{i + 1}" for i in range(1, len(inputs))), "y")
        names = [
            sel if isinstance(sel, str) else default
            for sel, default in zip((*inputs, output), defaults, strict=True)
        ]
        if name is None:
            name = stored.get("name") or path.stem
        more_units = {
            key: unit
            for key, unit in zip(names[1:-1], units[2:-1], strict=True)
            if unit is not None
        }
        options = {
            key: unit
            for key, unit in (
                ("time_unit", units[0]),
                ("input_unit", units[1]),
                ("output_unit", units[-1]),
            )
            if unit is not None
        }
        try:
            return cls(
                columns[0],
                columns[1],
                columns[-1],
                name=name,
                input_name=names[0],
                output_name=names[-1],
                resample=resample,
                more_inputs=dict(zip(names[1:-1], columns[2:-1], strict=True)),
                more_input_units=more_units,
                **options,
            )
        except RecordingError as error:
            raise RecordingError(
                f"{path}: {error}", cli=f"{str(path)!r}: {error.cli_message}"
            ) from None

    @classmethod
    def _load_quasi_static(
        cls,
        path: Path,
        input: str | int | None,
        output: str | int | None,
        header: bool,
        name: str | None,
    ) -> "Recording":
        if path.suffix.lower() not in (".csv", ".txt"):
            raise RecordingError(
                f"time=None reads two-column .csv/.txt files, not "
                f"{path.suffix!r} ({str(path)!r}); load the arrays yourself and build "
                "Recording.quasi_static(displacement, force).",
                owner="Recording.load",
                cli=f"--no-time reads two-column .csv/.txt files, not "
                f"{path.suffix!r} ({str(path)!r}); export displacement and force as "
                "a two-column .csv, or drop --no-time and name the arrays with "
                "--time/--input/--output.",
            )
        selectors = (0 if input is None else input, 1 if output is None else output)
        columns, units = _read_text(path, selectors, header, two_columns=True)
        meta = {
            f"{role}_{kind}": value
            for role, selector, unit in zip(
                ("input", "output"), selectors, units, strict=True
            )
            for kind, value in (
                ("unit", unit),
                ("name", selector if isinstance(selector, str) else None),
            )
            if value is not None
        }
        try:
            return cls.quasi_static(
                *columns,
                name=path.stem if name is None else name,
                **meta,
            )
        except RecordingError as error:
            raise RecordingError(
                f"{path}: {error}", cli=f"{str(path)!r}: {error.cli_message}"
            ) from None

    def save(self, path: str | os.PathLike, *, overwrite: bool = False) -> None:
        """Write to `.csv` (header "t,<input_name>,<output_name>", units in
        brackets), `.npz` or `.mat` (arrays under those names plus the metadata).
        Further inputs are written after `u` (a CSV then starts with the comment line
        "# jaxhyst inputs: u, v", which `load` reads them back by).

        Refuses to replace an existing file unless `overwrite=True`.
        """
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix not in (".csv", ".npz", ".mat"):
            raise RecordingError(
                f"unknown file type {path.suffix!r} of "
                f"{str(path)!r}; use .csv, .npz or .mat.",
                owner="Recording.save",
            )
        refuse_existing(path, overwrite=overwrite, refusal=Refusal("Recording.save"))
        names = ("t", *self.input_names, self.output_name)
        values = (self.t, self.u, *self.more_inputs, self.y)
        if len(set(names)) < len(names) or any(
            n.startswith(_META_PREFIX) for n in names
        ):
            raise RecordingError(
                f"column names {names} must be distinct and must not "
                f"start with {_META_PREFIX!r}; rename the input/output first.",
                owner="Recording.save",
            )
        if suffix == ".csv":
            units = (
                self.time_unit,
                self.input_unit,
                *self.more_input_units,
                self.output_unit,
            )
            head = [f"{n} [{u}]" if u else n for n, u in zip(names, units, strict=True)]
            with open(path, "w", newline="") as file:
                if self.more_input_names:
                    file.write(_INPUTS_MARK + ", ".join(self.input_names) + "\n")
                csv.writer(file).writerow(head)
                np.savetxt(file, np.stack(values, axis=1), delimiter=",", fmt="%.17g")
            return
        arrays = dict(zip(names, values, strict=True))
        meta: dict[str, Any] = {
            _META_PREFIX + key: getattr(self, key)
            for key in ("name", "input_unit", "output_unit", "time_unit")
        }
        if self.more_input_names:
            meta[_META_PREFIX + "inputs"] = list(self.input_names)
            meta[_META_PREFIX + "input_units"] = [
                self.input_unit,
                *self.more_input_units,
            ]
        if suffix == ".npz":
            if {"file", "allow_pickle"} & set(names):
                raise RecordingError(
                    f"column names {names} clash with np.savez "
                    "arguments ('file', 'allow_pickle'); save as .mat or .csv, or "
                    "rename the input/output.",
                    owner="Recording.save",
                )
            payload: dict[str, Any] = {
                **arrays,
                **{k: np.array(v) for k, v in meta.items()},
            }
            with open(path, "wb") as file:
                np.savez(file, **payload)
        else:
            import scipy.io

            for n in names:
                if not _MAT_NAME.fullmatch(n):
                    raise RecordingError(
                        f"{n!r} is not a valid MAT variable name "
                        "(letters, digits, underscores, starting with a letter); "
                        "save as .npz or .csv, or rename the input/output.",
                        owner="Recording.save",
                    )
            scipy.io.savemat(path, {**arrays, **meta}, appendmat=False)


# ----------------------------------------------------------------------- readers


def _split_unit(cell: str) -> tuple[str, str | None]:
    match = _UNIT_SUFFIX.match(cell)
    if match is None:
        return cell, None
    return match.group(1).strip(), match.group(2).strip()


def _read_text(
    path: Path,
    selectors: Sequence[str | int],
    header: bool,
    *,
    two_columns: bool = False,
) -> tuple[list[np.ndarray], list[str | None]]:
    """The selected columns (time, the inputs, output; or input, output when
    `two_columns`, which also requires exactly two equally long columns), and the
    unit each one's header names (None where it names none)."""
    lines = [
        (number, line)
        for number, line in enumerate(_decoded(path).splitlines(), start=1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not lines:
        raise RecordingError(
            f"{str(path)!r} is empty; pass a file with data rows.",
            owner="Recording.load",
        )
    first = lines[0][1]
    delimiter = next((d for d in (",", ";", "\t") if d in first), None)
    if delimiter is None:
        rows = [line.split() for _, line in lines]
    else:
        rows = list(csv.reader((line for _, line in lines), delimiter=delimiter))
    numbers = [number for number, _ in lines]
    names: list[str] | None = None
    if header:
        names = [cell.strip().strip("\"'").strip() for cell in rows[0]]
        rows, numbers = rows[1:], numbers[1:]
        if not rows:
            raise RecordingError(
                f"{str(path)!r} has a header row but no data rows.",
                owner="Recording.load",
            )
    width = len(names) if names is not None else len(rows[0])
    if two_columns:
        _check_two_columns(path, rows, numbers, width)
    roles = _roles(len(selectors), two_columns)
    units: list[str | None] = []
    indices = []
    for role, selector in zip(roles, selectors, strict=True):
        index, unit = _column_index(path, role, selector, names, width)
        indices.append(index)
        units.append(unit)

    labels = [
        f"column {s!r}" + (f" (index {i})" if isinstance(s, str) else "")
        for s, i in zip(selectors, indices, strict=True)
    ]
    columns = [np.empty(len(rows)) for _ in indices]
    for r, (row, number) in enumerate(zip(rows, numbers, strict=True)):
        for column, index, label in zip(columns, indices, labels, strict=True):
            if index >= len(row):
                raise RecordingError(
                    f"{str(path)!r} line {number} has {len(row)} "
                    f"cells, so {label} is missing; fix or drop that line.",
                    owner="Recording.load",
                )
            cell = row[index].strip()
            try:
                column[r] = float(cell)
            except ValueError:
                what = "is empty" if not cell else f"holds {cell!r}, not a number"
                if re.fullmatch(r"[-+]?\d*,\d+", cell):
                    what += " (a decimal comma: write numbers with a decimal point)"
                raise RecordingError(
                    f"{str(path)!r} line {number}, {label} {what}; "
                    "fix or drop that line, or check the column selection.",
                    owner="Recording.load",
                ) from None
    return columns, units


# Control characters that do not occur in a text file (all but tab, newline, form
# feed and carriage return).
_BINARY_BYTES = bytes(set(range(32)) - {9, 10, 12, 13})


def _decoded(path: Path) -> str:
    """The text of the file at `path`: UTF-8 (with or without a byte-order mark),
    UTF-16 or UTF-32 with a byte-order mark, else Latin-1 (every byte a character,
    as Windows tools write "\u00b5m"). A file with control bytes (a binary file, or
    UTF-16 without a byte-order mark) raises `RecordingError`."""
    data = path.read_bytes()
    for mark, encoding in (
        (b"\xff\xfe\x00\x00", "utf-32"),
        (b"\x00\x00\xfe\xff", "utf-32"),
        (b"\xff\xfe", "utf-16"),
        (b"\xfe\xff", "utf-16"),
    ):
        if data.startswith(mark):
            try:
                return data.decode(encoding)
            except UnicodeDecodeError:
                break
    else:
        where = next((i for i, b in enumerate(data) if b in _BINARY_BYTES), None)
        if where is None:
            try:
                return data.decode("utf-8-sig")
            except UnicodeDecodeError:
                return data.decode("latin-1")
    fix = (
        "pass a text file (comma-, semicolon-, tab- or whitespace-separated "
        "numbers, saved as UTF-8), or give a NumPy or MATLAB file its .npz or .mat "
        "suffix"
    )
    raise RecordingError(
        f"{str(path)!r} is not a text file (it holds binary bytes); {fix}.",
        owner="Recording.load",
    )


def _roles(count: int, two_columns: bool = False) -> list[str]:
    """What each selected column is, for messages: time, input(s), output."""
    if two_columns:
        return ["input", "output"]
    return ["time", *(["input"] * (count - 2)), "output"]


# `save` marks a CSV of several inputs with this comment line, so that `load` reads
# them all back.
_INPUTS_MARK = "# jaxhyst inputs: "


def _saved_inputs(path: Path, suffix: str) -> tuple[str, ...]:
    """The inputs `save` wrote to `path` (empty if it did not mark them)."""
    if suffix in (".csv", ".txt"):
        first = next(iter(_decoded(path).splitlines()), "").strip()
        if first.startswith(_INPUTS_MARK):
            return tuple(n.strip() for n in first[len(_INPUTS_MARK) :].split(","))
        return ()
    stored = _stored_arrays(path, suffix[1:]).get(_META_PREFIX + "inputs")
    if stored is None or np.asarray(stored).dtype.kind != "U":
        return ()
    return tuple(str(n).strip() for n in np.asarray(stored).ravel())


def _saved_output(path: Path, suffix: str, inputs: tuple[str, ...]) -> str | None:
    """The output column of a file `save` wrote with several `inputs` (the one
    column that is neither the time "t" nor an input), else None."""
    if suffix in (".csv", ".txt"):
        lines = _decoded(path).splitlines()
        head = next(csv.reader(lines[1:2]), [])
        names = [_split_unit(cell)[0] for cell in head]
    else:
        names = [
            key
            for key in _stored_arrays(path, suffix[1:])
            if not key.startswith(_META_PREFIX) and not key.startswith("__")
        ]
    rest = [n for n in names if n not in ("t", *inputs)]
    return rest[0] if len(rest) == 1 else None


def _check_two_columns(
    path: Path, rows: list[list[str]], numbers: list[int], width: int
) -> None:
    """Refuse a file read without time unless it has two equally long columns."""
    where = repr(str(path))
    owner = "Recording.load"
    wide = next(
        ((n, len(r)) for r, n in zip(rows, numbers, strict=True) if len(r) > 2), None
    )
    if width > 2 or wide is not None:
        number, cells = wide if wide is not None else (numbers[0], width)
        problem = (
            f"{where} line {number} has {cells} columns; without a time column the "
            "file must have exactly two (displacement, force)"
        )
        raise RecordingError(
            f"{problem}: drop the others, or read it with its time column.",
            owner=owner,
            cli=f"{problem}: drop the others, or drop --no-time and pick the columns "
            "with --time/--input/--output (with --no-header, by 0-based index).",
        )
    if max(len(r) for r in rows) < 2:
        raise RecordingError(
            f"{where} has one column; without a time column the file must have "
            "exactly two (displacement, force), one pair per line.",
            owner=owner,
        )
    counts = [sum(len(r) > i and bool(r[i].strip()) for r in rows) for i in (0, 1)]
    if counts[0] != counts[1]:
        short = next(
            n
            for r, n in zip(rows, numbers, strict=True)
            if len(r) < 2 or not r[0].strip() or not r[1].strip()
        )
        raise RecordingError(
            f"{where} has two columns of different lengths ({counts[0]} and "
            f"{counts[1]} values, the first short row at line {short}); pass one "
            "force value per displacement value, on the same line.",
            owner=owner,
        )


def _column_index(
    path: Path,
    role: str,
    selector: str | int,
    names: list[str] | None,
    width: int,
) -> tuple[int, str | None]:
    if isinstance(selector, bool) or not isinstance(selector, int | str):
        raise TypeError(
            f"Recording.load: {role} must be a column name (str) or index (int), "
            f"got {type(selector).__name__}."
        )
    if isinstance(selector, int):
        if not 0 <= selector < width:
            columns = f"{str(path)!r} has {width} columns (indices 0 to {width - 1})"
            raise RecordingError(
                f"{role}={selector} is out of range; {columns}.",
                owner="Recording.load",
                cli=f"--{role} {selector} is out of range: {columns}; pick one of "
                "them"
                + (
                    " (a file of displacement and force without time is read with "
                    "--no-time)."
                    if width == 2
                    else "."
                ),
            )
        unit = None
        if names is not None:
            unit = _split_unit(names[selector])[1]
        return selector, unit
    if names is None:
        raise RecordingError(
            f"{role}={selector!r} selects a column by name, but "
            "header=False; pass integer column indices (e.g. time=0, input=1, "
            "output=2) or header=True.",
            owner="Recording.load",
            cli=f"--{role} {selector!r} names a column, but with --no-header columns "
            f"are picked by 0-based index; pass e.g. --{role} "
            f"{('time', 'input', 'output').index(role)}, or drop --no-header.",
        )
    if selector in names:
        return names.index(selector), None
    for index, cell in enumerate(names):
        bare, unit = _split_unit(cell)
        if bare == selector:
            return index, unit
    where = f"{str(path)!r} has no column {selector!r} for {role}"
    available = f"available columns: {', '.join(map(repr, names))}"
    if not all(_is_number(cell) for cell in names if cell):
        if width == 2 and role == "time":
            fix = (
                "name the time column with --time; a file of displacement and force "
                "without time is read with --no-time, without its header row"
            )
        else:
            fix = f"pick one with --{role}"
        raise RecordingError(
            f"{where}; {available}.",
            owner="Recording.load",
            cli=f"{where}; {available}; {fix}.",
        )
    # The "names" are the first row's numbers: the file has no header.
    first = ", ".join(names)
    if width == 2:
        python_fix = (
            "time=None reads displacement and force without time, or pass "
            "header=False and integer column indices"
        )
        cli_fix = (
            "its two columns read as displacement and force (no time) with --no-time"
        )
    else:
        python_fix = "pass header=False and integer column indices"
        cli_fix = (
            "pass --no-header (columns by 0-based index: by default --time 0 --input "
            "1 --output 2)"
        )
    headless = f"its first row ({first}) holds numbers, so it seems to have no header"
    raise RecordingError(
        f"{where}; {available}; the first row looks numeric, so the file may have no "
        f"header: {python_fix}.",
        owner="Recording.load",
        cli=f"{where}: {headless}; {cli_fix}.",
    )


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def _stored_arrays(path: Path, kind: str) -> dict[str, Any]:
    """Every array of a `.npz` (`kind` "npz") or `.mat` file, by name."""
    if kind == "npz":
        try:
            # Opened here, so that a file np.load cannot read is closed as well.
            with (
                open(path, "rb") as handle,
                np.load(handle, allow_pickle=False) as data,
            ):
                arrays = {key: data[key] for key in data.files}
        except (OSError, ValueError, EOFError, zipfile.BadZipFile):
            raise RecordingError(
                f"{str(path)!r} is not a NumPy .npz archive, or it is truncated; "
                "pass a whole file written by np.savez.",
                owner="Recording.load",
                cli=f"{str(path)!r} is not a NumPy .npz archive, or it is truncated; "
                "pass a whole .npz file (as numpy.savez writes it), or the data as "
                ".csv.",
            ) from None
    else:
        import scipy.io

        try:
            arrays = {
                key: value
                for key, value in scipy.io.loadmat(path).items()
                if not key.startswith("__")
            }
        except NotImplementedError:
            raise RecordingError(
                f"{str(path)!r} is a MATLAB v7.3 (HDF5) file; save "
                "it with '-v7' in MATLAB or read it with h5py and build "
                "Recording(t, u, y).",
                owner="Recording.load",
                cli=f"{str(path)!r} is a MATLAB v7.3 (HDF5) file; save it with '-v7' "
                "in MATLAB, or export the data as .csv.",
            ) from None
        except (OSError, ValueError, EOFError, scipy.io.matlab.MatReadError):
            raise RecordingError(
                f"{str(path)!r} is not a MATLAB .mat file, or it is truncated; pass a "
                "whole file saved by MATLAB's save (or scipy.io.savemat).",
                owner="Recording.load",
                cli=f"{str(path)!r} is not a MATLAB .mat file, or it is truncated; "
                "pass a whole .mat file (MATLAB's save -v7), or the data as .csv.",
            ) from None
    if not arrays:
        raise RecordingError(
            f"{str(path)!r} is empty; it holds no arrays.",
            owner="Recording.load",
        )
    return arrays


def _text(value: Any) -> list[str] | None:
    """A stored string (array) as a list of strings, None if it is not text."""
    if value is None or np.asarray(value).dtype.kind != "U":
        return None
    return [str(v).strip() for v in np.asarray(value).ravel()]


def _read_arrays(
    path: Path, selectors: Sequence[str | int], kind: str
) -> tuple[list[np.ndarray], list[str | None], dict[str, str]]:
    """The selected arrays (time, the inputs, output), the unit stored for each (None
    where none is), and the stored recording name (key "name", if any)."""
    arrays = _stored_arrays(path, kind)
    meta = {
        key: _text(arrays.pop(_META_PREFIX + key, None))
        for key in (
            "name",
            "input_unit",
            "output_unit",
            "time_unit",
            "inputs",
            "input_units",
        )
    }
    # Units as `save` stored them: by input name for the inputs.
    input_units = dict(zip(meta["inputs"] or (), meta["input_units"] or ()))
    first_input = (meta["inputs"] or [None])[0]
    if first_input is not None and meta["input_unit"]:
        input_units.setdefault(first_input, meta["input_unit"][0])
    roles = _roles(len(selectors))
    units: list[str | None] = []
    columns = []
    for role, selector in zip(roles, selectors, strict=True):
        if not isinstance(selector, str):
            raise RecordingError(
                f"select {kind} arrays by key name, got "
                f"{role}={selector!r}; available keys: "
                f"{', '.join(map(repr, arrays))}.",
                owner="Recording.load",
                cli=f"--{role} {selector}: the arrays of {str(path)!r} are picked by "
                f"name, not index; available: {', '.join(map(repr, arrays))}.",
            )
        if selector not in arrays:
            raise RecordingError(
                f"{str(path)!r} has no array {selector!r} for {role}; "
                f"available keys: {', '.join(map(repr, arrays))}.",
                owner="Recording.load",
                cli=f"{str(path)!r} has no array {selector!r} for {role}; available: "
                f"{', '.join(map(repr, arrays))}; pick one with --{role}.",
            )
        value = np.asarray(arrays[selector])
        if value.dtype.kind not in "biuf":
            raise RecordingError(
                f"array {selector!r} in {str(path)!r} has dtype "
                f"{value.dtype}, not real numbers; select a numeric array.",
                owner="Recording.load",
            )
        if sum(d > 1 for d in value.shape) > 1:
            raise RecordingError(
                f"array {selector!r} in {str(path)!r} has shape "
                f"{value.shape}; pass a single channel of shape (N,), (1, N) or (N, 1).",
                owner="Recording.load",
            )
        columns.append(value.ravel())
        if role == "time":
            units.append((meta["time_unit"] or [None])[0])
        elif role == "output":
            units.append((meta["output_unit"] or [None])[0])
        elif meta["inputs"] is None and selector == selectors[1]:
            units.append((meta["input_unit"] or [None])[0])
        else:
            units.append(input_units.get(selector))
    stored = {"name": meta["name"][0]} if meta["name"] else {}
    return columns, units, stored


def column_names(path: str | os.PathLike) -> tuple[str, ...] | None:
    """The names `Recording.load` can select in `path`: a text file's header cells
    (a unit in brackets left out), the arrays of a `.npz` or `.mat` file. None where
    the file cannot be read so (`Recording.load` says why)."""
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        if suffix in (".npz", ".mat"):
            arrays = _stored_arrays(path, suffix[1:])
            return tuple(key for key in arrays if not key.startswith(_META_PREFIX))
        if suffix not in (".csv", ".txt"):
            return None
        with open(path, encoding="utf-8-sig", newline="") as file:
            lines = (line.strip() for line in file)
            first = next((x for x in lines if x and not x.startswith("#")), None)
    except (OSError, UnicodeDecodeError, RecordingError):
        return None
    if first is None:
        return None
    delimiter = next((d for d in (",", ";", "\t") if d in first), None)
    cells = (
        first.split()
        if delimiter is None
        else next(csv.reader([first], delimiter=delimiter), [])
    )
    return tuple(_split_unit(cell.strip().strip("\"'").strip())[0] for cell in cells)
