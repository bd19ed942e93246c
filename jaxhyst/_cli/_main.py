"""The parser of the `jaxhyst` command line and `main`, which runs a command and
turns user errors into one line on stderr."""

import argparse
import dataclasses
import importlib
import importlib.metadata
import os
import sys
import traceback
from collections.abc import Sequence
from typing import NoReturn

import jax

from .._cache import enable_compilation_cache
from .._recording import RecordingError
from ._options import PROG, one_line
from ._programs import install_program_store
from ._words import SOURCES, cli_words


# The commands in the order `jaxhyst --help` lists them; each is the module
# `jaxhyst._cli._<name>`, imported only when its parser is needed (a command line
# naming one command imports that one: `jaxhyst fit` does not import the diagnosis).
COMMANDS = (
    "simulate",
    "fit",
    "diagnose",
    "evaluate",
    "compensate",
    "batch",
    "demo",
)


class UsageError(Exception):
    """A command line that argparse rejected: the message, and the (sub)command's
    prog for the `--help` hint."""

    def __init__(self, prog: str, message: str):
        super().__init__(message)
        self.prog = prog


@dataclasses.dataclass(frozen=True)
class DeclaredOption:
    """A long option as a command declares it: its flag (`--no-time`), whether it is
    a switch (takes no value) and whether it may be repeated (`--input u --input v`)."""

    flag: str
    switch: bool
    repeat: bool


class CommandParser(argparse.ArgumentParser):
    """An ArgumentParser that raises instead of printing usage and exiting, so that
    `main` reports every error in the same one-line form, and that keeps what was
    declared on it: its long options and its commands' parsers."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.declared_options: dict[str, DeclaredOption] = {}
        self.commands: dict[str, CommandParser] = {}

    def _declare(self, action: argparse.Action, kwargs: dict) -> argparse.Action:
        for flag in action.option_strings:
            if flag.startswith("--") and flag not in ("--help", "--version"):
                self.declared_options[flag] = DeclaredOption(
                    flag=flag,
                    switch=action.nargs == 0,
                    repeat=kwargs.get("action") in ("append", "extend"),
                )
        return action

    def add_argument(self, *args, **kwargs):
        return self._declare(super().add_argument(*args, **kwargs), kwargs)

    def add_argument_group(self, *args, **kwargs):
        group = super().add_argument_group(*args, **kwargs)
        add = group.add_argument

        def add_and_declare(*args, **kwargs):
            return self._declare(add(*args, **kwargs), kwargs)

        group.add_argument = add_and_declare
        return group

    def error(self, message: str) -> NoReturn:
        raise UsageError(self.prog, message)


class _Version(argparse.Action):
    """`--version`: prints jaxhyst's version (read only when asked for) and exits."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, **kwargs):
        super().__init__(option_strings, dest, nargs=0, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        from .. import __version__

        print(f"{parser.prog} {__version__}")  # on stdout, as argparse's own
        parser.exit()


def _named_command(argv: Sequence[str]) -> str | None:
    """The command `argv` names (its first argument, when that is one), else None."""
    return argv[0] if argv and argv[0] in COMMANDS else None


def build_parser(argv: Sequence[str] | None = None) -> CommandParser:
    """The `jaxhyst` parser. Given the command line it will parse, and that names a
    command, it declares that command only (importing only its module); otherwise
    every command (for `--help`, and for the error on an unknown one)."""
    named = None if argv is None else _named_command(argv)
    parser = CommandParser(
        prog=PROG,
        description=(
            "Bouc-Wen hysteresis models in JAX: simulate, identify, diagnose. "
            "Run 'jaxhyst COMMAND --help' for a command's options. Compiled "
            "programs are cached on disk so that later runs start faster "
            "(JAXHYST_CACHE_DIR moves the cache; an empty value turns it off)."
        ),
    )
    parser.add_argument(
        "--version", action=_Version, help="show the version number and exit"
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMANDS if named is None else (named,):
        importlib.import_module(f"{__package__}._{name}").add_parser(subparsers)
        parser.commands[name] = subparsers.choices[name]
    return parser


def command_parser(command: str) -> CommandParser:
    """The parser of `jaxhyst COMMAND` alone; its `declared_options` are the command's
    long options."""
    return build_parser([command]).commands[command]


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
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(argv)
    SOURCES.clear()
    try:
        args = parser.parse_args(argv)
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
        print(f"{PROG}: error: {cli_words(error)}", file=sys.stderr)
        return 2
    except (ValueError, TypeError) as error:
        if not raised_by_jaxhyst(error):
            raise  # a bug (in jaxhyst's use of a library, or in one): its traceback
        print(f"{PROG}: error: {cli_words(error)}", file=sys.stderr)
        return 2


# Commands that run each of their programs once or a few times: compiling is most of
# their time, and XLA:CPU's elemental emitters compile in about half of it (a
# diagnosis, which runs its programs dozens of times, keeps XLA's default, whose code
# ran its refits 15-35 % faster; benchmarks/HISTORY.md, sessions 34 and 36).
QUICK_COMPILE_COMMANDS = ("simulate", "fit", "evaluate", "compensate")
_QUICK_COMPILE_FLAG = "--xla_cpu_use_fusion_emitters=false"
# jaxlib releases known to have the flag (XLA aborts on one it does not know).
_QUICK_COMPILE_JAXLIB = ((0, 6), (0, 11))


def _jaxlib_version() -> tuple[int, ...]:
    try:
        text = importlib.metadata.version("jaxlib")
    except importlib.metadata.PackageNotFoundError:
        return ()
    return tuple(int(part) for part in text.split(".")[:2] if part.isdigit())


def quick_compile_flags(argv: Sequence[str], environ: dict[str, str]) -> str | None:
    """The `XLA_FLAGS` a command line should run with, or None to leave them as they
    are: the elemental emitters for `QUICK_COMPILE_COMMANDS`, unless the user's
    `XLA_FLAGS` chooses the emitters or jaxlib is not one known to have the flag."""
    flags = environ.get("XLA_FLAGS", "")
    low, high = _QUICK_COMPILE_JAXLIB
    if (
        _named_command(argv) not in QUICK_COMPILE_COMMANDS
        or "xla_cpu_use_fusion_emitters" in flags
        or not low <= _jaxlib_version() < high
    ):
        return None
    return f"{flags} {_QUICK_COMPILE_FLAG}".strip()


PROGRAM_STORE_VAR = "JAXHYST_PROGRAM_STORE"


def store_programs() -> None:
    """Keep exported programs beside the compilation cache (`_programs`), unless
    the cache is off or `JAXHYST_PROGRAM_STORE=0`. For processes that run commands
    only (the console script, a batch's workers): tests that call `main` in-process
    never see it."""
    if os.environ.get(PROGRAM_STORE_VAR, "1") == "0":
        return
    folder = enable_compilation_cache()
    if folder is None:
        return
    try:
        install_program_store(folder / "programs")
    except OSError:
        pass  # no store: every program is traced, as without one


def script() -> NoReturn:
    """The `jaxhyst` console script and `python -m jaxhyst`: `main()`, then the
    process ends at once with its exit status (`os._exit`, after flushing stdout
    and stderr), as mypy does. Python's normal shutdown (collecting every module's
    objects, tearing down JAX's runtime and its compiled programs) took 0.35 s of a
    2.7 s warm `jaxhyst fit`, and there is nothing left for it to do: every file a
    command writes is closed before `main` returns, and JAX writes its cache when it
    compiles. An exception escaping `main` (a bug)
    takes Python's normal path, traceback included. Before JAX starts its backend it
    sets the command's XLA flags (`quick_compile_flags`): an application's choice,
    made here at the edge and not by the library."""
    flags = quick_compile_flags(sys.argv[1:], dict(os.environ))
    if flags is not None:
        os.environ["XLA_FLAGS"] = flags
    store_programs()
    status = main()
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except BrokenPipeError:  # e.g. `jaxhyst ... | head`: the reader is gone
        pass
    os._exit(status)
