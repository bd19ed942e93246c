"""The parser of the `jaxhyst` command line and `main`, which runs a command and
turns user errors into one line on stderr."""

import argparse
import os
import sys
import traceback
from collections.abc import Sequence
from typing import NoReturn

import jax

from .._cache import enable_compilation_cache
from .._program_store import prefetching
from .._recording import RecordingError
from . import _compensate, _demo, _diagnose, _evaluate, _fit, _simulate
from ._options import PROG, one_line


# The commands in the order `jaxhyst --help` lists them.
_COMMANDS = (_simulate, _fit, _diagnose, _evaluate, _compensate, _demo)


class UsageError(Exception):
    """A command line that argparse rejected: the message, and the (sub)command's
    prog for the `--help` hint."""

    def __init__(self, prog: str, message: str):
        super().__init__(message)
        self.prog = prog


class _Parser(argparse.ArgumentParser):
    """An ArgumentParser that raises instead of printing usage and exiting, so that
    `main` reports every error in the same one-line form."""

    def error(self, message: str) -> NoReturn:
        raise UsageError(self.prog, message)


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__

    parser = _Parser(
        prog=PROG,
        description=(
            "Bouc-Wen hysteresis models in JAX: simulate, identify, diagnose. "
            "Run 'jaxhyst COMMAND --help' for a command's options. Compiled "
            "programs are cached on disk so that later runs start faster "
            "(JAXHYST_CACHE_DIR moves the cache; an empty value turns it off)."
        ),
    )
    parser.add_argument(
        "--version", action="version", version=f"%(prog)s {__version__}"
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for command in _COMMANDS:
        command.add_parser(subparsers)
    return parser


_PACKAGE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def raised_by_jaxhyst(error: BaseException) -> bool:
    """Whether a `raise` statement in jaxhyst's own code raised `error`: the checks
    of what the user gave (a bad option value, a model file that does not fit the
    recording), which the command line reports in one line. A `ValueError` or
    `TypeError` raised inside JAX, NumPy or another library is a bug in how jaxhyst
    used it, or in that library, and keeps its traceback."""
    frames = traceback.extract_tb(error.__traceback__)
    if not frames:
        return False
    last = frames[-1]
    inside = os.path.abspath(last.filename).startswith(_PACKAGE + os.sep)
    return inside and (last.line or "").lstrip().startswith("raise")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line with `argv` (default: `sys.argv[1:]`); returns the exit
    status: 0 on success, 2 on a user error (reported as one line on stderr)."""
    enable_compilation_cache()
    jax.config.update("jax_enable_x64", True)
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        with prefetching():
            return args.run(args)
    except UsageError as error:
        print(
            f"{PROG}: error: {one_line(error)} (see '{error.prog} --help')",
            file=sys.stderr,
        )
        return 2
    except SystemExit as stop:  # --help and --version
        return stop.code if isinstance(stop.code, int) else 0
    except (RecordingError, ImportError, OSError) as error:
        print(f"{PROG}: error: {one_line(error)}", file=sys.stderr)
        return 2
    except (ValueError, TypeError) as error:
        if not raised_by_jaxhyst(error):
            raise  # a bug (in jaxhyst's use of a library, or in one): its traceback
        print(f"{PROG}: error: {one_line(error)}", file=sys.stderr)
        return 2


def script() -> NoReturn:
    """The `jaxhyst` console script and `python -m jaxhyst`: `main()`, then the
    process ends at once with its exit status (`os._exit`, after flushing stdout
    and stderr), as mypy does. Python's normal shutdown (collecting every module's
    objects, tearing down JAX's runtime and its compiled programs) took 0.35 s of a
    2.7 s warm `jaxhyst fit`, and there is nothing left for it to do: every file a
    command writes is closed before `main` returns, and JAX and the program store
    write their caches when they compile. An exception escaping `main` (a bug)
    takes Python's normal path, traceback included."""
    status = main()
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except BrokenPipeError:  # e.g. `jaxhyst ... | head`: the reader is gone
        pass
    os._exit(status)
