"""Blocks (`_blocks.py`) as Markdown: blocks separated by one blank line."""

from collections.abc import Sequence

from ._blocks import Block, Bullets, Heading, Image, Item, Paragraph, Table


def _row(cells: Sequence[str]) -> str:
    return "| " + " | ".join(cells) + " |"


def _block(block: Block) -> str:
    if isinstance(block, Heading):
        return f"{'#' * block.level} {block.text}"
    if isinstance(block, Paragraph):
        return block.text
    if isinstance(block, Table):
        rule = "|" + "|".join("---:" if a == "r" else "---" for a in block.align) + "|"
        return "\n".join([_row(block.header), rule, *map(_row, block.rows)])
    if isinstance(block, Bullets):
        lines = []
        for item in block.items:
            if isinstance(item, Item):
                lines.append(f"- {item.text}")
                lines += [f"  - {sub}" for sub in item.items]
            else:
                lines.append(f"- {item}")
        return "\n".join(lines)
    if isinstance(block, Image):
        image = f"![{block.alt}]({block.link})"
        return f"{block.caption}\n\n{image}" if block.caption else image
    raise TypeError(f"to_markdown: not a report block: {type(block).__name__}.")


def to_markdown(blocks: Sequence[Block]) -> str:
    """The Markdown text of `blocks`."""
    return "\n\n".join(_block(block) for block in blocks) + "\n"
