"""XLA compiler options that jaxhyst's programs (`stored_jit`) may ask for, and what
becomes of them where XLA does not know them or `XLA_FLAGS` names them.

`ELEMENTAL_EMITTERS` asks XLA:CPU for its older elemental IR emitters instead of the
MLIR fusion emitters recent jaxlibs use by default. Measured on jaxhyst's programs
(benchmarks/HISTORY.md, session 34), it halves their compile time, but what it gives
runs at the same speed only for some: the Levenberg-Marquardt polish ran as fast
or faster, while the swarm's loop, the identifiability Jacobian and the diagnosis's
predictions ran 10-35 % slower on 45 000-sample records. So only the programs that
lose nothing ask for it (the polish, and small one-shot programs). Other backends
ignore the option; an XLA that does not know it compiles without it; and where
`XLA_FLAGS` names it, `XLA_FLAGS` decides.
"""

import functools
import os

import jax


ELEMENTAL_EMITTERS = {"xla_cpu_use_fusion_emitters": False}

# Options left out where this XLA does not know them or `XLA_FLAGS` names them
# (the others are passed on as they are: a wrong one is an error).
_OPTIONAL = frozenset(ELEMENTAL_EMITTERS)


def compiler_options(requested: dict | None) -> dict:
    """The options a program compiles with: `requested` less the optional ones that
    `XLA_FLAGS` names (the user's choice). Part of a stored executable's key."""
    flags = os.environ.get("XLA_FLAGS", "")
    return {
        name: value
        for name, value in (requested or {}).items()
        if not (name in _OPTIONAL and f"--{name}" in flags)
    }


def supported(options: dict) -> dict:
    """`options` less the optional ones this XLA does not know."""
    return {
        name: value
        for name, value in options.items()
        if name not in _OPTIONAL or _known(name, value)
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
