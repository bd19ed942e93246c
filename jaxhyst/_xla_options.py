"""The XLA compiler options jaxhyst's own programs (`stored_jit`) are compiled with.

XLA:CPU's MLIR fusion emitters, the default of recent jaxlibs, took about twice as
long to compile jaxhyst's programs (the swarm's RK4 loop, the Levenberg-Marquardt
polish, the identifiability Jacobian) as its older elemental emitters, and ran them
no faster (benchmarks/HISTORY.md, session 34): a fresh `jaxhyst fit` spends about
4 s compiling instead of 7 s. So jaxhyst asks for the older emitters. Other backends
ignore the option; an XLA that does not know it (another jaxlib) compiles without
it; and where `XLA_FLAGS` names it, `XLA_FLAGS` decides.
"""

import functools
import os

import jax


_LIBRARY_OPTIONS: dict[str, bool | int | float | str] = {
    "xla_cpu_use_fusion_emitters": False,
}


def compiler_options(extra: dict | None = None) -> dict:
    """The options a jaxhyst program asks for: the library's (less those `XLA_FLAGS`
    names), then `extra` (a program's own, e.g. the swarm's vector width), which
    win. Part of a stored executable's key (`stored_jit`)."""
    flags = os.environ.get("XLA_FLAGS", "")
    chosen = {k: v for k, v in _LIBRARY_OPTIONS.items() if f"--{k}" not in flags}
    return {**chosen, **(extra or {})}


def supported(options: dict) -> dict:
    """`options` less the library's own that this XLA does not know (a program's own
    options are passed on as they are: a wrong one is an error)."""
    return {
        name: value
        for name, value in options.items()
        if name not in _LIBRARY_OPTIONS or _known(name, value)
    }


@functools.cache
def _known(name: str, value: bool | int | float | str) -> bool:
    """Whether XLA accepts the option `name=value` (asked once per process, by
    compiling an empty program with it, only when a program is compiled)."""
    try:
        jax.jit(lambda: None, compiler_options={name: value}).lower().compile()
    except RuntimeError as error:  # jax.errors.JaxRuntimeError
        if "No such compile option" in str(error):
            return False
        raise
    return True
