"""A report as a list of typed blocks, written once and rendered twice: to Markdown
(`_markdown.py`) and to self-contained HTML (`_html.py`).

Text in a block is Markdown inline text of exactly these constructs: `**bold**`,
`` `code` `` and `[label](link)`; the HTML renderer converts them, and escapes
everything else.
"""

import dataclasses
from collections.abc import Sequence
from pathlib import Path


@dataclasses.dataclass(frozen=True)
class Heading:
    """A heading; `level` 1 is the report's title."""

    text: str
    level: int = 2


@dataclasses.dataclass(frozen=True)
class Paragraph:
    """A paragraph (a blank line in `text` starts another)."""

    text: str


@dataclasses.dataclass(frozen=True)
class Table:
    """A table: a header row, the body rows, and one alignment per column ("l" or
    "r")."""

    header: Sequence[str]
    rows: Sequence[Sequence[str]]
    align: str

    def __post_init__(self):
        widths = {len(self.header), len(self.align), *(len(row) for row in self.rows)}
        if len(widths) != 1 or not set(self.align) <= {"l", "r"}:
            raise ValueError(
                "Table: the header, every row and align (of 'l'/'r') must have one "
                f"entry per column, got widths {sorted(widths)}."
            )


@dataclasses.dataclass(frozen=True)
class Item:
    """A list item with a nested list under it."""

    text: str
    items: Sequence[str] = ()


@dataclasses.dataclass(frozen=True)
class Bullets:
    """A bulleted list; an entry is its text, or an `Item` with a nested list."""

    items: Sequence[str | Item]


@dataclasses.dataclass(frozen=True)
class Image:
    """A figure: the PNG `file` (embedded in HTML), `link` to it from the report
    (Markdown), its `alt` text, and an optional `caption` above it."""

    file: Path
    link: str
    alt: str
    caption: str = ""


Block = Heading | Paragraph | Table | Bullets | Image
"""One block of a report."""


def title_of(blocks: Sequence[Block]) -> str:
    """The text of the first level-1 heading ("" if none)."""
    for block in blocks:
        if isinstance(block, Heading) and block.level == 1:
            return block.text
    return ""
