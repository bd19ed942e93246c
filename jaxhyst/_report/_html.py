"""Blocks (`_blocks.py`) as one self-contained HTML file: the figures embedded as
base64 PNG data URIs, a little inline CSS, no external assets, no scripts, so that
the file can be mailed and opened anywhere.

Inline text is Markdown of three constructs (`**bold**`, `` `code` ``,
`[label](link)`), converted here; everything else is escaped.
"""

import base64
import html
import re
from collections.abc import Sequence
from pathlib import Path

from ._blocks import Block, Bullets, Heading, Image, Item, Paragraph, Table, title_of


_STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, sans-serif;
  line-height: 1.5; color: #1b1b1b; max-width: 60rem; margin: 2rem auto;
  padding: 0 1rem; }
h1, h2, h3 { line-height: 1.25; }
h2 { border-bottom: 1px solid #ddd; padding-bottom: 0.2em; margin-top: 2em; }
table { border-collapse: collapse; margin: 1em 0; display: block; overflow-x: auto; }
th, td { border: 1px solid #ccc; padding: 0.3em 0.6em; vertical-align: top; }
th { background: #f3f3f3; }
td.r, th.r { text-align: right; font-variant-numeric: tabular-nums; }
code { background: #f3f3f3; padding: 0.1em 0.3em; border-radius: 3px; }
figure { margin: 1.5em 0; }
figcaption { margin-bottom: 0.5em; }
img { max-width: 100%; height: auto; }
""".strip()

_INLINE = re.compile(r"`([^`]+)`|\*\*(.+?)\*\*|\[([^\]]+)\]\(([^)\s]+)\)")


def _text(text: str) -> str:
    return html.escape(text, quote=False)


def inline(text: str) -> str:
    """Markdown inline text (`**bold**`, `` `code` ``, `[label](link)`) as HTML."""
    out, start = [], 0
    for match in _INLINE.finditer(text):
        out.append(_text(text[start : match.start()]))
        code, bold, label, link = match.groups()
        if code is not None:
            out.append(f"<code>{_text(code)}</code>")
        elif bold is not None:
            out.append(f"<strong>{inline(bold)}</strong>")
        else:
            out.append(f'<a href="{html.escape(link)}">{inline(label)}</a>')
        start = match.end()
    out.append(_text(text[start:]))
    return "".join(out)


def _cells(tag: str, cells: Sequence[str], align: str) -> str:
    inner = "".join(
        f'<{tag} class="{a}">{inline(cell)}</{tag}>' for cell, a in zip(cells, align)
    )
    return f"<tr>{inner}</tr>"


def _data_uri(file: Path, owner: str) -> str:
    try:
        data = Path(file).read_bytes()
    except FileNotFoundError:
        raise FileNotFoundError(
            f"{owner}: the figure {str(file)!r} does not exist, and the HTML report "
            "embeds its figures; write the figures first."
        ) from None
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def _block(block: Block, owner: str) -> str:
    if isinstance(block, Heading):
        return f"<h{block.level}>{inline(block.text)}</h{block.level}>"
    if isinstance(block, Paragraph):
        parts = [p.strip() for p in block.text.split("\n\n") if p.strip()]
        return "\n".join(f"<p>{inline(p)}</p>" for p in parts)
    if isinstance(block, Table):
        head = _cells("th", block.header, block.align)
        body = "\n".join(_cells("td", row, block.align) for row in block.rows)
        return f"<table>\n<thead>{head}</thead>\n<tbody>\n{body}\n</tbody>\n</table>"
    if isinstance(block, Bullets):
        items = []
        for item in block.items:
            if isinstance(item, Item):
                nested = "".join(f"<li>{inline(sub)}</li>" for sub in item.items)
                nested = f"<ul>{nested}</ul>" if nested else ""
                items.append(f"<li>{inline(item.text)}{nested}</li>")
            else:
                items.append(f"<li>{inline(item)}</li>")
        return "<ul>\n" + "\n".join(items) + "\n</ul>"
    if isinstance(block, Image):
        caption = (
            f"<figcaption>{inline(block.caption)}</figcaption>" if block.caption else ""
        )
        image = (
            f'<img src="{_data_uri(block.file, owner)}" alt="{html.escape(block.alt)}">'
        )
        return f"<figure>{caption}{image}</figure>"
    raise TypeError(f"{owner}: not a report block: {type(block).__name__}.")


def to_html(blocks: Sequence[Block], *, owner: str = "to_html") -> str:
    """One self-contained HTML document of `blocks` (figures embedded). `owner`
    names the caller in errors (a figure file missing)."""
    title = re.sub(r"[`*]", "", title_of(blocks)) or "jaxhyst report"
    body = "\n".join(_block(block, owner) for block in blocks)
    return (
        "<!DOCTYPE html>\n"
        '<html lang="en">\n'
        "<head>\n"
        '<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        '<meta name="generator" content="jaxhyst">\n'
        f"<title>{_text(title)}</title>\n"
        f"<style>\n{_STYLE}\n</style>\n"
        "</head>\n"
        "<body>\n"
        "<main>\n"
        f"{body}\n"
        "</main>\n"
        "</body>\n"
        "</html>\n"
    )
