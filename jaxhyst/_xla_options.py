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

The swarm's loop and the identifiability Jacobian ask for it only in a *one-shot*
run (`one_shot()`: `identify`, which runs each once), where their compilation is
most of their cost (the swarm's loop: 1.2-1.5 s to compile, about 0.6 s to run in a
fit). Work that runs them many times (a diagnosis's refits: `repeated_runs()`)
compiles them with XLA's default, whose code runs faster; so does everything
outside both blocks (`run_swarm` called on its own, as a benchmark does). The two
are separate executables, each kept in the program store. The mode is a context
variable: the threads jaxhyst starts for a block (`preparing`, `side_by_side`) run
in a copy of their caller's context, and other threads start outside both.
"""

import contextlib
import contextvars
import enum
import functools
import os
from collections.abc import Iterator

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


class _Runs(enum.Enum):
    UNSAID = enum.auto()  # outside both blocks
    ONE_SHOT = enum.auto()
    REPEATED = enum.auto()


_runs: contextvars.ContextVar[_Runs] = contextvars.ContextVar(
    "jaxhyst_runs", default=_Runs.UNSAID
)


@contextlib.contextmanager
def _running(mode: _Runs) -> Iterator[None]:
    token = _runs.set(mode)
    try:
        yield
    finally:
        _runs.reset(token)


def one_shot() -> contextlib.AbstractContextManager[None]:
    """A block that runs its programs once (a fit): programs with one-shot options
    (`stored_jit(one_shot_options=...)`) compile with them, unless the block is
    inside `repeated_runs()` (a diagnosis's fits), which it leaves as it is."""
    return _running(_Runs.REPEATED if _runs.get() is _Runs.REPEATED else _Runs.ONE_SHOT)


def repeated_runs() -> contextlib.AbstractContextManager[None]:
    """A block that runs the same programs many times (a diagnosis): they compile
    with their usual options, one-shot blocks inside it included."""
    return _running(_Runs.REPEATED)


def in_one_shot() -> bool:
    """Whether the caller is in a `one_shot()` block (and not in `repeated_runs()`)."""
    return _runs.get() is _Runs.ONE_SHOT
