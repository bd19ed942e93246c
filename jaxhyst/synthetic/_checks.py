"""Argument checks shared by the synthetic generators (before any work is done)."""

import math
from collections.abc import Mapping

import numpy as np


NOISE_KINDS: tuple[str, ...] = ("white", "coloured")


def _check_positive(owner: str, name: str, value) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        raise TypeError(f"{owner}: {name} must be a number, got {value!r}.")
    if not (value > 0 and math.isfinite(value)):
        raise ValueError(
            f"{owner}({name}={value}): {name} must be positive and finite."
        )


def _validate_effects(effects, names: tuple[str, ...], owner: str) -> tuple[str, ...]:
    """`effects` checked against the catalogue's `names`, in catalogue order."""
    if isinstance(effects, str):
        raise TypeError(
            f"{owner}: effects must be a tuple of effect names, e.g. ({effects!r},), "
            "not a string."
        )
    try:
        effects = tuple(effects)
    except TypeError:
        raise TypeError(
            f"{owner}: effects must be a tuple of effect names, got "
            f"{type(effects).__name__}; pass e.g. ({names[0]!r},) or () for a clean "
            "record."
        ) from None
    unknown = [e for e in effects if e not in names]
    if unknown:
        raise ValueError(
            f"{owner}: unknown effect(s) {unknown}; valid names are "
            f"{', '.join(names)} (an empty tuple gives a clean recording)."
        )
    if len(set(effects)) != len(effects):
        raise ValueError(f"{owner}: effects {effects} name an effect twice.")
    return tuple(e for e in names if e in effects)


def _validate_sizes(size_sigmas, effects, owner: str) -> dict[str, float] | None:
    """The requested sizes per effect, or None where they are to be drawn."""
    if size_sigmas is None:
        return None
    if isinstance(size_sigmas, Mapping):
        extra = sorted(set(size_sigmas) - set(effects))
        missing = sorted(set(effects) - set(size_sigmas))
        if extra or missing:
            raise ValueError(
                f"{owner}: size_sigmas names {sorted(size_sigmas)} but the effects "
                f"are {list(effects)}; give one size per effect (or a single number)."
            )
        sizes = {e: size_sigmas[e] for e in effects}
    else:
        sizes = {e: size_sigmas for e in effects}
    for effect, size in sizes.items():
        if isinstance(size, bool) or not isinstance(size, (int, float, np.number)):
            raise TypeError(
                f"{owner}: size of {effect!r} must be a number, got {size!r}."
            )
        if not (size > 0 and math.isfinite(size)):
            raise ValueError(
                f"{owner}: size of {effect!r} is {size}; sizes are positive numbers "
                "of noise sigmas, e.g. size_sigmas=5.0."
            )
    return {e: float(s) for e, s in sizes.items()}


def _validate_noise(noise, owner: str) -> str:
    """The noise kind ("colored" reads as "coloured")."""
    if noise == "colored":
        noise = "coloured"
    if noise not in NOISE_KINDS:
        raise ValueError(
            f"{owner}(noise={noise!r}): noise must be one of {', '.join(NOISE_KINDS)}."
        )
    return noise
