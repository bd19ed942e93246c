"""The one JSON serialiser: every JSON file the package and the command line write
(fit and diagnosis results, model files) is `dumps` of its data, and every checksum
is over `canonical` JSON.

Strict JSON throughout (`allow_nan=False`): JSON has no NaN or infinity, and a
file with them is not read by every JSON reader; `jsonable` turns non-finite
numbers into null first.
"""

import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ._files import Refusal, refuse_existing


def jsonable(value: Any) -> Any:
    """`value` with every NumPy/JAX scalar or array turned into Python numbers and
    lists, tuples into lists, and non-finite floats into None, so that
    `json.dumps(..., allow_nan=False)` accepts it (strict JSON has no NaN)."""
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        number = float(value)
        return number if math.isfinite(number) else None
    if isinstance(value, str) or value is None:
        return value
    if hasattr(value, "shape") and hasattr(value, "dtype"):  # NumPy or JAX array
        array = np.asarray(value)
        return jsonable(array.item() if array.ndim == 0 else array.tolist())
    raise TypeError(f"jsonable: cannot convert {type(value).__name__} to JSON.")


def dumps(data: Any) -> str:
    """`jsonable(data)` as indented strict JSON (the text of every JSON file)."""
    return json.dumps(jsonable(data), indent=2, allow_nan=False)


def canonical(data: Any) -> str:
    """`data` as canonical JSON (sorted keys, no whitespace), for checksums. Not
    passed through `jsonable`: a non-finite number raises `ValueError` rather than
    being checksummed as null."""
    return json.dumps(data, sort_keys=True, separators=(",", ":"), allow_nan=False)


def write_json(
    data: Any,
    path: str | os.PathLike,
    *,
    overwrite: bool,
    refusal: Refusal = Refusal("write_json"),
) -> Path:
    """Write `jsonable(data)` as indented strict JSON; refuses to replace an
    existing file unless `overwrite` (`refusal`: the words of that refusal). Returns
    the path."""
    path = Path(path)
    text = dumps(data)
    refuse_existing(path, overwrite=overwrite, refusal=refusal)
    path.write_text(text + "\n", encoding="utf-8")
    return path
