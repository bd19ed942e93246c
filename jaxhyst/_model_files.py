"""Model files: a fitted or diagnosed model saved as JSON and loaded back exactly.

The format (`format_version` 1), one JSON object:

    {
      "format": "jaxhyst-model",
      "format_version": 1,
      "jaxhyst_version": "0.1.0",
      "model": {
        "class": "PiezoBoucWen",
        "parameters": {"k1": 2.9e-05, ...},     every `parameter_names` entry
        "smoothing": {"rule": "TanhSign", "width": 0.001},
        "fields": {"input_scale": 4.0, ...}     every other field ({} if none)
      },
      "family": "piezo" | "structural" | null,  the diagnosis family, if any
      "effects": ["creep", ...],                the effects a diagnosis adopted
      "units": {"input": "V", "output": "m", "time": "s"},   "" where unknown
      "recordings": [{"name": ..., "samples": ..., "sample_rate_hz": ...,
                      "input_range": [min u, max u],
                      "inputs": ["u", "v"], "output": "y"}],
      "checksum": "sha256:<hex>"
    }

A recording's "inputs" and "output" are the columns it was read from (its
`input_names` and `output_name`): `jaxhyst evaluate` and `compensate` read the
same columns of another file unless told otherwise. They are left out where the
names are not columns (a recording read without header or time column, or given
its command by --command-level); files written before they existed load as
before, and a jaxhyst that does not know them ignores them.

Numbers are stored with `repr` precision, so float64 parameters load bit-for-bit.
The checksum is the SHA-256 of the canonical JSON of every other key (sorted keys,
no whitespace): a file edited by hand is refused unless loaded with `verify=False`.
`jaxhyst fit --json` and `jaxhyst diagnose --json` embed the same object under the
key "model_file"; `load_model` reads such files directly.
"""

import dataclasses
import hashlib
import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import equinox as eqx
import numpy as np

from ._files import Refusal, refuse_folder
from ._models.base import AbstractHysteresisModel
from ._models.bouc_wen import BoucWen, CorrectedPiezoBoucWen, PiezoBoucWen, PiezoStage
from ._models.damper import BoucWenDamper, SpencerDamper
from ._models.damper_extended import ExtendedDamper
from ._models.extended import ExtendedPiezo
from ._models.oscillator import HystereticOscillator
from ._models.structural import StructuralBoucWen
from ._recording import Recording
from ._serialise import canonical, write_json
from ._smoothing import AbstractSmoothing, AlgebraicSign, ExactSign, TanhSign


FORMAT = "jaxhyst-model"
FORMAT_VERSION = 1
# The key under which the fit and diagnose JSON of the command line embed a model file.
EMBEDDED_KEY = "model_file"

# The only classes a model file can name: nothing else is ever imported or built.
MODEL_CLASSES: dict[str, type[AbstractHysteresisModel]] = {
    cls.__name__: cls
    for cls in (
        BoucWen,
        PiezoBoucWen,
        CorrectedPiezoBoucWen,
        PiezoStage,
        HystereticOscillator,
        StructuralBoucWen,
        ExtendedPiezo,
        BoucWenDamper,
        SpencerDamper,
        ExtendedDamper,
    )
}
SMOOTHING_RULES: dict[str, type[AbstractSmoothing]] = {
    cls.__name__: cls for cls in (ExactSign, TanhSign, AlgebraicSign)
}
_TOP_KEYS: tuple[str, ...] = (
    "format",
    "format_version",
    "jaxhyst_version",
    "model",
    "family",
    "effects",
    "units",
    "recordings",
    "checksum",
)
_UNIT_KEYS = ("input", "output", "time")


class LoadedModel(eqx.Module):
    """What `load_model` returns: the `model`, ready to `simulate`, and what the
    file says about it: the `units` of its input, output and time ("" where
    unknown), the `recordings` it was fitted to (name, samples, sample_rate_hz,
    input_range, and the inputs and output columns where known; empty if not
    recorded), the diagnosis `family` and adopted `effects` (None and
    () for a plain fit), and the `jaxhyst_version` that wrote it."""

    model: AbstractHysteresisModel
    units: dict[str, str]
    recordings: tuple[dict[str, Any], ...]
    family: str | None
    effects: tuple[str, ...]
    jaxhyst_version: str

    @property
    def input_range(self) -> tuple[float, float] | None:
        """(min, max) of the input over the recordings it was fitted to: the range
        inside which the model interpolates. None when the file records no
        recording, or one without its input range."""
        ranges = [r.get("input_range") for r in self.recordings]
        known = [(float(r[0]), float(r[1])) for r in ranges if r is not None]
        if not known or len(known) < len(ranges):
            return None
        return min(lo for lo, _ in known), max(hi for _, hi in known)

    @property
    def columns(self) -> tuple[tuple[str, ...], str] | None:
        """The columns the model was fitted from: the inputs it reads (the first
        `len(model.input_names)` of the recordings' inputs, in order) and the
        output, by their names in the recordings. None when the file records no
        names (an older file, or names that were not columns) or the recordings
        name them differently."""
        named = {_columns(r) for r in self.recordings}
        found = named.pop() if len(named) == 1 else None
        needed = len(self.model.input_names)
        if found is None or len(found[0]) < needed:
            return None
        return found[0][:needed], found[1]

    def check_units(self, recording: Recording, where: str) -> None:
        """Refuse a recording whose declared input/output units differ from the
        model's (where both declare one): the errors would be off by the
        conversion. `where` names the recording in the message."""
        for key in ("input", "output"):
            ours, theirs = self.units[key], getattr(recording, f"{key}_unit")
            if ours and theirs and ours != theirs:
                raise ValueError(
                    f"{where}: its {key} is in {theirs}, the model's in {ours}; "
                    "convert the recording to the model's units."
                )


def _columns(recording: Mapping[str, Any]) -> tuple[tuple[str, ...], str] | None:
    """A recording entry's input and output column names, None unless it records
    them (non-empty strings)."""
    inputs, output = recording.get("inputs"), recording.get("output")
    if not (isinstance(inputs, list) and inputs and isinstance(output, str)):
        return None
    if not (output and all(isinstance(n, str) and n for n in inputs)):
        return None
    return tuple(inputs), output


def _version() -> str:
    from . import __version__

    return __version__


def _known(registry: Mapping[str, type]) -> str:
    return ", ".join(sorted(registry))


def _number(value: Any, what: str) -> float:
    """`value` (a Python or NumPy/JAX scalar) as a finite float."""
    array = np.asarray(value)
    if array.shape != () or not np.issubdtype(array.dtype, np.number):
        raise TypeError(f"save_model: {what} = {value!r} is not a number.")
    number = float(array)
    if not math.isfinite(number):
        raise ValueError(
            f"save_model: {what} = {number} is not finite; a model file stores "
            "finite values only (check the fit's status)."
        )
    return number


def _field_value(value: Any, what: str) -> Any:
    """A non-parameter field as JSON: bool, int, float or a list of those."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, int):
        return value
    if isinstance(value, (tuple, list)):
        return [_field_value(v, f"{what}[{i}]") for i, v in enumerate(value)]
    return _number(value, what)


def _smoothing_dict(smoothing: AbstractSmoothing) -> dict[str, Any]:
    name = type(smoothing).__name__
    if SMOOTHING_RULES.get(name) is not type(smoothing):
        raise TypeError(
            f"save_model: the model's smoothing {name} cannot be saved; use one of "
            f"{_known(SMOOTHING_RULES)}."
        )
    out: dict[str, Any] = {"rule": name}
    for field in dataclasses.fields(smoothing):
        out[field.name] = _number(getattr(smoothing, field.name), f"smoothing.{name}")
    return out


def _unit(recordings: Sequence[Recording], key: str) -> str:
    found = sorted({getattr(r, f"{key}_unit") for r in recordings} - {""})
    if len(found) > 1:
        raise ValueError(
            f"save_model: the recordings' {key} units differ ({', '.join(found)}); "
            "one model has one unit: convert the recordings to the same units."
        )
    return found[0] if found else ""


def _recording_dict(recording: Recording, columns: bool) -> dict[str, Any]:
    """A "recordings" entry: the recording's size and input range, and with
    `columns` the names of its input and output columns."""
    entry: dict[str, Any] = {
        "name": recording.name,
        "samples": recording.num_samples,
        "sample_rate_hz": float(recording.sample_rate),
        "input_range": [float(np.min(recording.u)), float(np.max(recording.u))],
    }
    if columns:
        entry["inputs"] = list(recording.input_names)
        entry["output"] = recording.output_name
    return entry


def checksum(data: Mapping[str, Any]) -> str:
    """ "sha256:<hex>" of the canonical JSON (sorted keys, no whitespace) of every
    key of `data` but "checksum"."""
    rest = {k: v for k, v in data.items() if k != "checksum"}
    return "sha256:" + hashlib.sha256(canonical(rest).encode("utf-8")).hexdigest()


def model_file_dict(
    model: AbstractHysteresisModel,
    *,
    recording: Recording | Sequence[Recording] | None = None,
    family: str | None = None,
    effects: Sequence[str] = (),
    columns: bool = True,
) -> dict[str, Any]:
    """The model file's JSON object (with its checksum); see `save_model`."""
    cls = type(model)
    if MODEL_CLASSES.get(cls.__name__) is not cls:
        raise TypeError(
            f"save_model: {cls.__name__} cannot be saved; a model file holds one of "
            f"{_known(MODEL_CLASSES)}."
        )
    if family is not None and not isinstance(family, str):
        raise TypeError(f"save_model: family must be a string or None, got {family!r}.")
    if isinstance(effects, str) or not all(isinstance(e, str) for e in effects):
        raise TypeError(
            f"save_model: effects must be a sequence of effect names, got {effects!r}."
        )
    if recording is None:
        recordings: list[Recording] = []
    elif isinstance(recording, Recording):
        recordings = [recording]
    else:
        recordings = list(recording)
    for r in recordings:
        if not isinstance(r, Recording):
            raise TypeError(
                f"save_model: recording must be a Recording (or several), got "
                f"{type(r).__name__}."
            )
    parameters = {
        name: _number(getattr(model, name), f"{cls.__name__}.{name}")
        for name in cls.parameter_names
    }
    # Every other field but the smoothing (its own block) and ways of computing
    # (the gains a refit holds at zero): the model's `setting_names`.
    fields = {
        name: _field_value(getattr(model, name), f"{cls.__name__}.{name}")
        for name in cls.setting_names
    }
    data: dict[str, Any] = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "jaxhyst_version": _version(),
        "model": {
            "class": cls.__name__,
            "parameters": parameters,
            "smoothing": _smoothing_dict(model.smoothing),
            "fields": fields,
        },
        "family": family,
        "effects": list(effects),
        "units": {key: _unit(recordings, key) for key in _UNIT_KEYS},
        "recordings": [_recording_dict(r, columns) for r in recordings],
    }
    data["checksum"] = checksum(data)
    return data


def save_model(
    model: AbstractHysteresisModel,
    path: str | os.PathLike,
    *,
    recording: Recording | Sequence[Recording] | None = None,
    family: str | None = None,
    effects: Sequence[str] = (),
    columns: bool = True,
    overwrite: bool = False,
) -> Path:
    """Save `model` as a model file (JSON, format in the module docstring); returns
    the path.

    **Arguments:**

    - `model`: one of the package's models (`BoucWen`, `PiezoBoucWen`, ...), with
      its smoothing rule and every field.
    - `path`: the file to write.
    - `recording`: the `Recording` (or recordings) it was fitted to: their names,
      sizes, sample rates and units go into the file, and the names of their input
      and output columns (`input_names`, `output_name`), which `jaxhyst evaluate`
      and `compensate` read by default.
    - `columns`: False leaves the column names out, for recordings whose names are
      not columns of a file (read by index, or built with `with_input`).
    - `family`, `effects`: for a diagnosed model, the family's name and the
      adopted effects (`diagnosis.family`, `diagnosis.effects`).
    - `overwrite`: replace an existing file (refused otherwise).
    """
    data = model_file_dict(
        model, recording=recording, family=family, effects=effects, columns=columns
    )
    refuse_folder(path, owner="save_model")
    return write_json(
        data,
        path,
        overwrite=overwrite,
        refusal=Refusal("save_model", "overwrite=True", otherwise="pick another path"),
    )


def load_model(path: str | os.PathLike, *, verify: bool = True) -> LoadedModel:
    """Load a model file written by `save_model`, or the JSON of `jaxhyst fit
    --json` / `jaxhyst diagnose --json` (the fitted, or the final diagnosed, model:
    their "model_file" block). Returns a `LoadedModel` (`.model` and its metadata).

    Policy: a file is read only when its `format_version` is this version's (1);
    another format version is refused, naming both. A file written by another
    jaxhyst version with the same format version loads (`.jaxhyst_version` says
    which). With `verify=True` (default) the file's checksum must match its
    content, and in fit/diagnose JSON the visible parameters must match the
    embedded model, so a hand-edited file is refused rather than giving a
    silently different model; `verify=False` loads an edited model file (the
    embedded block of fit/diagnose JSON) as it stands. Unknown classes, smoothing
    rules, and missing or extra parameters and fields are always refused.
    """
    path = Path(path)
    owner = f"load_model({str(path)!r})"
    try:
        data = json.loads(path.read_text("utf-8"))
    except json.JSONDecodeError as error:
        raise ValueError(f"{owner}: not a JSON file ({error}).") from None
    if not isinstance(data, dict):
        raise ValueError(f"{owner}: not a jaxhyst model file (no JSON object).")
    if data.get("format") == FORMAT:
        return _from_dict(data, verify, owner)
    if EMBEDDED_KEY in data:
        block = data[EMBEDDED_KEY]
        if not isinstance(block, dict) or block.get("format") != FORMAT:
            raise ValueError(f"{owner}: its {EMBEDDED_KEY!r} is not a model file.")
        owner = f"{owner} ({EMBEDDED_KEY!r})"
        loaded = _from_dict(block, verify, owner)
        if verify:
            _check_visible(data, block, owner)
        return loaded
    if "model" in data and ("parameters" in data or "final" in data):
        raise ValueError(
            f"{owner}: this fit/diagnose JSON has no {EMBEDDED_KEY!r} block (written "
            "by an older jaxhyst, or by Fit.to_dict()); re-run 'jaxhyst fit --json' "
            "or 'jaxhyst diagnose --json', or save the model with jh.save_model."
        )
    raise ValueError(
        f'{owner}: not a jaxhyst model file (no "format": {FORMAT!r}); write one '
        "with jh.save_model, 'jaxhyst fit --json' or 'jaxhyst diagnose --json'."
    )


def _check_visible(data: dict[str, Any], block: dict[str, Any], owner: str) -> None:
    """The parameters fit/diagnose JSON shows must be the embedded model's: an
    edit there would otherwise be silently ignored."""
    if isinstance(data.get("final"), dict):
        visible = data["final"].get("parameters", {})
    else:
        visible = data.get("parameters", {})
    stored = block["model"]["parameters"]
    if not isinstance(visible, dict):
        visible = {}
    changed = sorted(
        name for name, value in visible.items() if stored.get(name, None) != value
    )
    if changed:
        raise ValueError(
            f"{owner}: the file was changed after it was written: its parameters "
            f"{changed} differ from the model it embeds; re-run the command, or "
            "pass verify=False to load the embedded model as written."
        )


def _from_dict(data: dict[str, Any], verify: bool, owner: str) -> LoadedModel:
    version = data.get("format_version")
    if version != FORMAT_VERSION:
        raise ValueError(
            f"{owner}: format version {version!r}, but this jaxhyst "
            f"({_version()}) reads format version {FORMAT_VERSION}; load it with the "
            f"jaxhyst that wrote it ({data.get('jaxhyst_version', 'unknown')}) and "
            "save it again, or refit."
        )
    if verify:
        stored = data.get("checksum")
        if not isinstance(stored, str):
            raise ValueError(
                f"{owner}: the file has no checksum; pass verify=False to load it "
                "anyway."
            )
        if stored != checksum(data):
            raise ValueError(
                f"{owner}: the file was changed after it was written (its checksum "
                "does not match its content); save the model again, or pass "
                "verify=False to load it as it stands."
            )
    extra = sorted(set(data) - set(_TOP_KEYS))
    missing = sorted(set(_TOP_KEYS) - set(data) - {"checksum"})
    if extra or missing:
        raise ValueError(
            f"{owner}: "
            + "; ".join(
                text
                for text in (
                    f"missing key(s) {missing}" if missing else "",
                    f"unknown key(s) {extra}" if extra else "",
                )
                if text
            )
            + f"; a format version {FORMAT_VERSION} file has {list(_TOP_KEYS)}."
        )
    model = _model(data["model"], owner)
    units = data["units"]
    if not (
        isinstance(units, dict)
        and set(units) == set(_UNIT_KEYS)
        and all(isinstance(v, str) for v in units.values())
    ):
        raise ValueError(
            f"{owner}: units must be {{'input', 'output', 'time'}} strings, got "
            f"{units!r}."
        )
    recordings = data["recordings"]
    if not (
        isinstance(recordings, list) and all(isinstance(r, dict) for r in recordings)
    ):
        raise ValueError(f"{owner}: recordings must be a list of objects.")
    family, effects = data["family"], data["effects"]
    if family is not None and not isinstance(family, str):
        raise ValueError(f"{owner}: family must be a string or null, got {family!r}.")
    if not (isinstance(effects, list) and all(isinstance(e, str) for e in effects)):
        raise ValueError(f"{owner}: effects must be a list of names, got {effects!r}.")
    jaxhyst_version = data["jaxhyst_version"]
    return LoadedModel(
        model=model,
        units={key: units[key] for key in _UNIT_KEYS},
        recordings=tuple(recordings),
        family=family,
        effects=tuple(effects),
        jaxhyst_version=str(jaxhyst_version),
    )


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _names_check(owner, what, given, expected) -> None:
    missing = [name for name in expected if name not in given]
    extra = sorted(set(given) - set(expected))
    if missing or extra:
        problems = []
        if missing:
            problems.append(f"missing {what} {missing}")
        if extra:
            problems.append(f"unknown {what} {extra}")
        raise ValueError(
            f"{owner}: {'; '.join(problems)}; the model has {what} {list(expected)}."
        )


def _json_field(value: Any, default: Any, name: str, owner: str) -> Any:
    """A field read back, of the kind of its default: bool, a tuple of numbers
    (stored as a list) or a number."""
    if isinstance(default, bool):
        ok, expected = isinstance(value, bool), "true or false"
    elif isinstance(default, tuple):
        ok = isinstance(value, list) and all(_is_number(v) for v in value)
        expected = "a list of numbers"
    else:
        ok, expected = _is_number(value), "a number"
    if not ok:
        raise ValueError(f"{owner}: field {name} = {value!r} must be {expected}.")
    return tuple(float(v) for v in value) if isinstance(value, list) else value


def _model(block: Any, owner: str) -> AbstractHysteresisModel:
    if not isinstance(block, dict):
        raise ValueError(f'{owner}: "model" must be an object.')
    _names_check(owner, "key(s)", block, ("class", "parameters", "smoothing", "fields"))
    name = block["class"]
    cls = MODEL_CLASSES.get(name) if isinstance(name, str) else None
    if cls is None:
        raise ValueError(
            f"{owner}: unknown model class {name!r}; a model file holds one of "
            f"{_known(MODEL_CLASSES)}."
        )
    parameters, fields = block["parameters"], block["fields"]
    if not isinstance(parameters, dict) or not isinstance(fields, dict):
        raise ValueError(f"{owner}: parameters and fields must be objects.")
    retired = [k for k in parameters if k in cls.retired_parameters]
    if retired:
        reasons = sorted({cls.retired_parameters[k] for k in retired})
        raise ValueError(
            f"{owner}: this {name} was written by an earlier jaxhyst: its "
            f"parameter(s) {retired} are {'; '.join(reasons)}; refit the model "
            "(jaxhyst diagnose or jh.identify) and save it again."
        )
    _names_check(owner, "parameter(s)", parameters, cls.parameter_names)
    bad = [k for k, v in parameters.items() if not _is_number(v)]
    if bad:
        raise ValueError(f"{owner}: parameter(s) {bad} must be numbers.")
    settings = set(cls.setting_names)
    other = {f.name: f for f in dataclasses.fields(cls) if f.name in settings}
    _names_check(owner, "field(s)", fields, tuple(other))
    values: dict[str, Any] = {k: float(v) for k, v in parameters.items()}
    for key, value in fields.items():
        values[key] = _json_field(value, other[key].default, key, owner)
    values["smoothing"] = _smoothing(block["smoothing"], owner)
    try:
        return cls(**values)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{owner}: cannot build {name}: {error}") from error


def _smoothing(block: Any, owner: str) -> AbstractSmoothing:
    rule = block.get("rule") if isinstance(block, dict) else None
    cls = SMOOTHING_RULES.get(rule) if isinstance(rule, str) else None
    if cls is None or not isinstance(block, dict):
        raise ValueError(
            f"{owner}: unknown smoothing {block!r}; the rule is one of "
            f"{_known(SMOOTHING_RULES)}."
        )
    expected = tuple(f.name for f in dataclasses.fields(cls))
    given = {k: v for k, v in block.items() if k != "rule"}
    _names_check(owner, f"{rule} field(s)", given, expected)
    bad = [k for k, v in given.items() if not _is_number(v)]
    if bad:
        raise ValueError(f"{owner}: {rule} field(s) {bad} must be numbers.")
    try:
        return cls(**{k: float(v) for k, v in given.items()})
    except (TypeError, ValueError) as error:
        raise ValueError(f"{owner}: cannot build {rule}: {error}") from error
