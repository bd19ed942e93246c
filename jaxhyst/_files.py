"""The one rule for writing output files: never replace an existing file unless
asked to, and never write a file where a folder is (or a folder where a file is).

Every writer of the package and the command line checks its outputs here, so the
rule and its messages are written once. Who speaks, and the fix a message names,
differ: the library says `pass overwrite=True`, the command line `pass --force`;
a `Refusal` carries those words. The checks create nothing (`output_folder` with
`create=True` makes the folder once everything passed), so a command can check
all its outputs before any computation and fail without leaving anything behind.
"""

import dataclasses
import os
from collections.abc import Iterable, Sequence
from pathlib import Path


@dataclasses.dataclass(frozen=True)
class Refusal:
    """The words of a refusal to replace existing files.

    - `owner`: who refuses, prefixed as "owner: ..." (None: no prefix).
    - `switch`: what to pass to replace the files.
    - `replaces`: what the switch replaces (None: "it" or "them").
    - `otherwise`: the other fix, after ", or " (None: none named).
    """

    owner: str | None = None
    switch: str = "overwrite=True (--force on the command line)"
    replaces: str | None = None
    otherwise: str | None = None


def _listed(paths: Sequence[Path]) -> str:
    names = [repr(str(path)) for path in paths]
    if len(names) == 1:
        return names[0]
    return f"{', '.join(names[:-1])} and {names[-1]}"


def _subject(path: Path, owner: str | None, option: str | None) -> str:
    """`path` as a message names it: after the option that named it ("--out
    'x'"), or after its owner ("save_model: 'x'")."""
    if option is not None:
        return f"{option} {str(path)!r}"
    if owner is not None:
        return f"{owner}: {str(path)!r}"
    return repr(str(path))


def refuse_existing(
    paths: str | os.PathLike | Iterable[str | os.PathLike],
    *,
    overwrite: bool,
    refusal: Refusal = Refusal(),
) -> None:
    """Raise `FileExistsError` naming every one of `paths` that exists, unless
    `overwrite`."""
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    if overwrite:
        return
    existing = [Path(path) for path in paths if Path(path).exists()]
    if not existing:
        return
    verb = "exists" if len(existing) == 1 else "exist"
    replaces = refusal.replaces or ("it" if len(existing) == 1 else "them")
    otherwise = f", or {refusal.otherwise}" if refusal.otherwise else ""
    prefix = f"{refusal.owner}: " if refusal.owner else ""
    raise FileExistsError(
        f"{prefix}{_listed(existing)} already {verb}; pass {refusal.switch} to "
        f"replace {replaces}{otherwise}."
    )


def refuse_folder(
    path: str | os.PathLike, *, owner: str | None = None, option: str | None = None
) -> None:
    """Raise `IsADirectoryError` if the output file `path` is a folder."""
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(
            f"{_subject(path, owner, option)} is a folder, not a file; pick a file "
            "name."
        )


def output_folder(
    folder: str | os.PathLike,
    names: Iterable[str],
    *,
    overwrite: bool,
    refusal: Refusal = Refusal(),
    option: str | None = None,
    create: bool = False,
) -> list[Path]:
    """The files `folder/name`, after checking that `folder` is (or can become) a
    folder, that none of the files is a folder, and that none exists unless
    `overwrite`. `option`: the command-line option that named `folder`, if any (its
    messages then name it). Creates `folder` (and its parents) only with `create`."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        fix = f"; pick another {option}" if option is not None else ""
        raise FileExistsError(
            f"{_subject(folder, refusal.owner, option)} is a file, not a folder{fix}."
        )
    paths = [folder / name for name in names]
    for path in paths:
        refuse_folder(path, owner=refusal.owner, option=option)
    refuse_existing(paths, overwrite=overwrite, refusal=refusal)
    if create:
        folder.mkdir(parents=True, exist_ok=True)
    return paths


def prepare_parent(path: str | os.PathLike) -> Path:
    """`path`, after creating its parent folder (and theirs) if missing."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return path
