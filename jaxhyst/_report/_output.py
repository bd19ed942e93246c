"""Writing a report: its Markdown and, next to it, the same as self-contained HTML,
both checked before either is written."""

import os
from collections.abc import Sequence
from pathlib import Path

from .._files import Refusal, refuse_existing, refuse_folder
from ._blocks import Block
from ._html import to_html
from ._markdown import to_markdown


def html_path(path: str | os.PathLike, owner: str | None = None) -> Path:
    """The HTML report written next to the Markdown report `path`: the same name
    with `.html` (report.md -> report.html). `owner` prefixes the error."""
    path = Path(path)
    if path.suffix.lower() in (".html", ".htm"):
        prefix = f"{owner}: " if owner else ""
        raise ValueError(
            f"{prefix}{str(path)!r} is the HTML report's name; pass the Markdown "
            "report's path (e.g. report.md): the HTML report goes next to it."
        )
    return path.with_suffix(".html")


def write_report(
    blocks: Sequence[Block],
    path: str | os.PathLike,
    *,
    overwrite: bool,
    owner: str,
    html: bool = True,
) -> list[Path]:
    """Write `blocks` as Markdown to `path` and, with `html`, as self-contained HTML
    next to it (`html_path`). Refuses, before writing either, to replace an
    existing file unless `overwrite`. Returns the paths written."""
    path = Path(path)
    paths = [path, html_path(path, owner)] if html else [path]
    for each in paths:
        refuse_folder(each, owner=owner)
    refuse_existing(paths, overwrite=overwrite, refusal=Refusal(owner))
    texts = [to_markdown(blocks)]
    if html:
        texts.append(to_html(blocks, owner=owner))
    for each, text in zip(paths, texts, strict=True):
        each.write_text(text, encoding="utf-8")
    return paths


def write_html(
    blocks: Sequence[Block], path: str | os.PathLike, *, overwrite: bool, owner: str
) -> Path:
    """Write `blocks` as self-contained HTML to `path`; refuses to replace an
    existing file unless `overwrite`. Returns the path."""
    path = Path(path)
    refuse_folder(path, owner=owner)
    refuse_existing(path, overwrite=overwrite, refusal=Refusal(owner))
    path.write_text(to_html(blocks, owner=owner), encoding="utf-8")
    return path
