"""The manifest of a batch: a CSV with one row per record, read and checked whole
before anything runs.

The header has `recording` (a path, absolute or relative to the manifest's folder)
and `command` (`diagnose` or `fit`). A column named after a long option of that
command without its dashes (`model`, `no_time`, `seed`, `input`, ...) sets that
option for the row (an empty cell leaves it unset; a switch such as `no_time` is on
for `1`, `true`, `yes` or `on`); a `name` column names the record's folder; every
other column is a label that the summary keeps. Each row's options are parsed by the
command's own parser, so a bad value is refused here, with its row.
"""

import csv
import dataclasses
import os
import re
from pathlib import Path
from typing import TYPE_CHECKING


if TYPE_CHECKING:
    from .._cli._main import CommandParser, DeclaredOption


COMMANDS = ("diagnose", "fit")
"""The commands a manifest row may run."""

OUTPUT_OPTIONS = ("json", "plots", "report", "force")
"""Options the batch sets itself (where each record's outputs go)."""

_TRUE = ("1", "true", "yes", "on", "y", "x")
_FALSE = ("0", "false", "no", "off", "n", "")


class ManifestError(ValueError):
    """A manifest that cannot run: the message names the file, the row (numbered as
    a spreadsheet shows it, the header being row 1) and the fix."""


@dataclasses.dataclass(frozen=True)
class Record:
    """One row of a manifest.

    - `name`: the record's folder under `OUT/records/` (unique in the manifest).
    - `row`: the row's number in the file (the header is row 1).
    - `recording`: the recording as the manifest writes it.
    - `path`: the recording's absolute path.
    - `command`: `diagnose` or `fit`.
    - `options`: the command-line options the row sets, e.g. `("--model",
      "bouc-wen", "--no-time")`, in the manifest's column order.
    - `labels`: the other columns, (column, value).
    """

    name: str
    row: int
    recording: str
    path: Path
    command: str
    options: tuple[str, ...]
    labels: tuple[tuple[str, str], ...]

    def argv(self) -> list[str]:
        """The command line of the record without its outputs."""
        return [self.command, str(self.path), *self.options]


@dataclasses.dataclass(frozen=True)
class Manifest:
    """A checked manifest: its file, its records in order, and the label columns."""

    path: Path
    records: tuple[Record, ...]
    label_columns: tuple[str, ...]


def _long_options(parser: "CommandParser") -> "dict[str, DeclaredOption]":
    """A command's long options by column name (`--no-time` -> `no_time`)."""
    return {
        flag[2:].replace("-", "_"): option
        for flag, option in parser.declared_options.items()
    }


def _safe_name(text: str) -> str:
    name = re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("._")
    return name or "record"


def _options(
    where: str,
    command: str,
    cells: dict[str, str],
    declared: "dict[str, DeclaredOption]",
) -> tuple[str, ...]:
    options: list[str] = []
    for column, value in cells.items():
        flag = "--" + column.replace("_", "-")
        option = declared[column]
        value = value.strip()
        if option.switch:
            if value.lower() not in _TRUE + _FALSE:
                raise ManifestError(
                    f"{where}: column {column!r} is a switch of 'jaxhyst {command}'; "
                    f"write 1 or 0 (yes/no), not {value!r}."
                )
            if value.lower() in _TRUE:
                options.append(flag)
        elif value:
            # A repeatable option (`input`) takes several values separated by
            # spaces or semicolons: `u v` is `--input u --input v`.
            for each in re.split(r"[;\s]+", value) if option.repeat else [value]:
                options += [flag, each]
    return tuple(options)


def read_manifest(path: str | os.PathLike) -> Manifest:
    """Read and check the manifest at `path`: every row's recording exists and its
    options parse. Raises `ManifestError` (one line naming the row and the fix) or
    `OSError` for a manifest that cannot be read."""
    path = Path(path)
    if not path.is_file():
        what = "is a folder" if path.is_dir() else "does not exist"
        raise ManifestError(f"manifest {str(path)!r} {what}; pass a CSV file.")
    with open(path, newline="", encoding="utf-8-sig") as file:
        rows = list(csv.reader(file))
    rows = [row for row in rows if any(cell.strip() for cell in row)]
    if not rows:
        raise ManifestError(
            f"manifest {str(path)!r} is empty; write a header row with the columns "
            "'recording' and 'command', then one row per record."
        )
    header = [cell.strip() for cell in rows[0]]
    for needed in ("recording", "command"):
        if needed not in header:
            raise ManifestError(
                f"manifest {str(path)!r}, row 1: no {needed!r} column (the header "
                f"is {', '.join(header)}); add it."
            )
    for column in header:
        if not column:
            raise ManifestError(
                f"manifest {str(path)!r}, row 1: a column without a name; name it "
                "or delete it."
            )
        if header.count(column) > 1:
            raise ManifestError(
                f"manifest {str(path)!r}, row 1: column {column!r} appears twice; "
                "keep one."
            )
    if len(rows) < 2:
        raise ManifestError(
            f"manifest {str(path)!r} has a header and no records; add one row per "
            "recording."
        )
    from .._cli._main import command_parser

    parsers = {command: command_parser(command) for command in COMMANDS}
    actions = {command: _long_options(parsers[command]) for command in COMMANDS}
    all_options = set().union(*(set(a) for a in actions.values()))
    labels = tuple(
        c
        for c in header
        if c not in ("recording", "command", "name") and c not in all_options
    )
    for column in header:
        if column in OUTPUT_OPTIONS:
            raise ManifestError(
                f"manifest {str(path)!r}, row 1: column {column!r} is set by the "
                "batch (each record's outputs go into OUT/records/NAME); delete the "
                "column."
            )

    records: list[Record] = []
    names: dict[str, int] = {}
    for number, row in enumerate(rows[1:], start=2):
        where = f"manifest {str(path)!r}, row {number}"
        if len(row) > len(header):
            raise ManifestError(
                f"{where}: {len(row)} cells under a header of {len(header)} columns; "
                "quote cells that hold commas, or add the missing column names."
            )
        cells = dict(zip(header, [c.strip() for c in row] + [""] * len(header)))
        command = cells["command"]
        if command not in COMMANDS:
            raise ManifestError(
                f"{where}: command {command!r}; write one of {', '.join(COMMANDS)}."
            )
        recording = cells["recording"]
        if not recording:
            raise ManifestError(f"{where}: the recording cell is empty; fill it in.")
        file = Path(recording).expanduser()
        file = file if file.is_absolute() else path.parent.absolute() / file
        if not file.is_file():
            what = "is a folder" if file.is_dir() else "does not exist"
            raise ManifestError(
                f"{where}: recording {str(file)!r} {what}; fix the path (a relative "
                "path is read from the manifest's folder)."
            )
        set_here = {
            c: v
            for c, v in cells.items()
            if c in all_options and c not in labels and v.strip()
        }
        for column in set_here:
            if column not in actions[command]:
                raise ManifestError(
                    f"{where}: column {column!r} is not an option of 'jaxhyst "
                    f"{command}'; leave the cell empty on {command} rows."
                )
        options = _options(where, command, set_here, actions[command])
        try:
            parsers[command].parse_args([str(file), *options])
        except Exception as error:  # the parser's UsageError: the bad value
            raise ManifestError(f"{where}: {error}; fix the cell.") from None
        name = _safe_name(cells.get("name") or file.stem)
        if name in names:
            if cells.get("name"):
                raise ManifestError(
                    f"{where}: name {name!r} is also row {names[name]}'s; give each "
                    "record its own name."
                )
            base, k = name, 2
            while name in names:
                name, k = f"{base}-{k}", k + 1
        names[name] = number
        records.append(
            Record(
                name=name,
                row=number,
                recording=recording,
                path=file,
                command=command,
                options=options,
                labels=tuple((c, cells[c]) for c in labels),
            )
        )
    return Manifest(path=path, records=tuple(records), label_columns=labels)
