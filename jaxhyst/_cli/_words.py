"""The command line's words for the library's errors: the one place that turns an
error the library raised (in Python words: `header=False`, `Recording.resample`,
class names) into the line `jaxhyst: error: ...` that names flags and files.

The library says how: a `RecordingError` carries its message without the owner
prefix (`problem`) and, where the fix differs on the command line, the message in
the command line's words (`cli`), both written where the error is raised, which
knows the file, the column and the fix. `in_file` names the file of an error that
the library raised about a recording's values (it does not know the file).

Errors without those fields (a `ValueError` of another module) are said as they
are, except for the few Python-only fixes in `PYTHON_FIXES`, which are replaced by
the command line's fix. `PYTHON_WORDS` lists what no command-line message may
contain; the tests check every message of the odd-file battery against it.
"""

import re

from .._recording import RecordingError


PYTHON_WORDS = ("=True", "=False", "Recording.", "DataScales", "InputPath")
"""Words of the Python API that a command-line message never contains."""

_EVERY_INPUT = "; read every input: --input repeated, e.g. --input u --input v"

PYTHON_FIXES: tuple[tuple[re.Pattern[str], str], ...] = (
    # identify / simulate: a recording with fewer inputs than the model reads.
    (
        re.compile(
            r"; load it with every input \(Recording\.load\(path, input=\[\.\.\.\]\), "
            r"or --input repeated on the command line: --input u --input v\)"
        ),
        _EVERY_INPUT,
    ),
    (
        re.compile(
            r"; build it with InputPath\(\.\.\., channels=\.\.\.\) or from a "
            r"Recording with more inputs \(Recording\(\.\.\., more_inputs=\.\.\.\), "
            r"--input repeated on the command line\)"
        ),
        _EVERY_INPUT,
    ),
    # the MR damper family on a record of one input.
    (
        re.compile(
            r", Recording\.load\(path, input=\['u', 'v'\]\), or Recording\(t, x, "
            r"force, more_inputs=\{'command': v\}\); for a test at one fixed "
            r"command, add it as a constant: rec\.with_input\('command', level\)"
        ),
        "; for a test at one fixed command, add the command as a column of that "
        "constant value",
    ),
    # a recording or path at another (or a non-uniform) rate.
    (re.compile(r"\s*\(Recording\.resample\)"), ""),
)
"""(pattern, replacement): fixes in Python words that messages of modules without
a `cli` field end with, and the command line's fix for each."""


def one_line(error: BaseException | str) -> str:
    """`error` (or a message) on one line: its words joined by single spaces (the
    error's class name where it has no message)."""
    text = " ".join(str(error).split())
    return text or type(error).__name__


SOURCES: dict[str, str] = {}
"""The file each recording the running command read came from, by the recording's
name (filled by `_options.load_recording`, emptied by `main` before a command), so
that an error about a recording (`RecordingError.recording`) names its file."""


def cli_words(error: BaseException) -> str:
    """`error` as the one line the command line prints after `jaxhyst: error: `."""
    if isinstance(error, RecordingError):
        text = one_line(error.cli_message)
        if error.recording is not None:
            source = SOURCES.get(error.recording)
            name = (
                repr(source) if source is not None else f"recording {error.recording!r}"
            )
            text = f"{name}: {text}"
        return text
    said = getattr(error, "cli_message", None)  # e.g. Recording.load's OSErrors
    if isinstance(said, str):
        return one_line(said)
    text = one_line(error)
    for pattern, replacement in PYTHON_FIXES:
        text = pattern.sub(replacement, text)
    return text


def in_file(path: str, error: RecordingError) -> RecordingError:
    """`error`, raised about the values of the recording read from `path`, with the
    file named (in both wordings)."""
    return RecordingError(
        f"{path!r}: {error}",
        cli=f"{path!r}: {error.cli_message}",
        kind=error.kind,
    )
