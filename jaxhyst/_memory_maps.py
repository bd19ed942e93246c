"""Compiled programs against the kernel's limit on memory maps (Linux).

XLA's CPU compiler maps each compiled kernel's code and data into memory
separately, so every compiled program holds a dozen memory maps or more (a
diagnosis of one real cyclic test compiles about 120 programs and adds about
5 600 maps), and JAX keeps thousands of compiled programs in its caches. A long
session that diagnoses or fits many records of different lengths (a notebook
looping over tests, a benchmark) then reaches Linux's per-process limit
(`vm.max_map_count`, 65 530 by default), and the next compilation fails with
"LLVM compilation error: Cannot allocate memory" although memory is free.
`release_if_near_map_limit` clears JAX's caches before that happens (at `RELEASE_AT` of the limit):
programs are compiled, or loaded, again when next needed.
"""

import gc
import warnings

import jax


_MAPS = "/proc/self/maps"
_LIMIT = "/proc/sys/vm/max_map_count"

# The share of the limit at which the caches are cleared. One diagnosis of a
# long real test adds up to about 10 000 maps (a sixth of the default limit),
# so 0.6 leaves room for one to finish. Lower it if the warning comes too late.
RELEASE_AT = 0.6


def memory_maps() -> tuple[int, int] | None:
    """(maps this process holds, the kernel's limit), or None where the system
    does not say (not Linux, or /proc unreadable)."""
    try:
        with open(_LIMIT, "rb") as file:
            limit = int(file.read().split()[0])
        with open(_MAPS, "rb") as file:
            used = file.read().count(b"\n")
    except (OSError, ValueError, IndexError):
        return None
    return used, limit


def release_if_near_map_limit(what: str) -> bool:
    """Clear JAX's compilation caches (`jax.clear_caches`) when this process holds
    at least `RELEASE_AT` of its memory-map limit, and warn saying so; `what`
    names the caller in the warning. Returns whether it cleared them."""
    counts = memory_maps()
    if counts is None:
        return False
    used, limit = counts
    if used < RELEASE_AT * limit:
        return False
    jax.clear_caches()
    gc.collect()
    after = memory_maps()
    warnings.warn(
        f"{what}: this process held {used} memory maps of the {limit} Linux allows "
        "it (vm.max_map_count), most of them JAX's compiled programs; jaxhyst "
        "cleared JAX's compilation caches"
        + (f" ({after[0]} maps left)" if after is not None else "")
        + " so that the next compilation does not fail with 'LLVM compilation "
        "error: Cannot allocate memory'. Programs are compiled again as needed; to "
        "keep them, raise the limit (sudo sysctl -w vm.max_map_count=262144).",
        RuntimeWarning,
        stacklevel=3,
    )
    return True
