"""Minimal Markdown → HTML for claims and study reports, and the one Markdown table writer.

:func:`markdown_to_html` renders headings, tables, lists and paragraphs; :class:`Table` and
:func:`table_markdown` are the only writer of Markdown tables (no other module writes a table
header or row by hand: ``tests/studies/test_report_package.py`` checks it). A leaf of the
output layer: the run report and the study report both import it, so neither imports the other.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

from otmm_qp.output.escape import escape

#: The style sheet of the run and study reports (one look for both).
REPORT_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:2rem auto;
max-width:1300px;padding:0 1rem;color:#1d2430;line-height:1.45}
h1{font-size:1.7rem;border-bottom:2px solid #2b5797;padding-bottom:.3rem}
h2{font-size:1.3rem;margin-top:2.2rem;color:#2b5797}h3{font-size:1.05rem;margin-top:1.4rem}
table{border-collapse:collapse;margin:.6rem 0 1rem;font-size:.86rem}
th,td{border:1px solid #cdd3dc;padding:.28rem .55rem;text-align:right;white-space:nowrap}
th{background:#eef2f7;text-align:center;white-space:normal}td:first-child,th:first-child{text-align:left}
tr:nth-child(even) td{background:#fafbfd}td.best{background:#d7f2dc!important;font-weight:700}
td.bad{color:#a4262c}td.name{white-space:normal;min-width:7rem;max-width:14rem}td.skip{color:#6b7280;font-style:italic;text-align:left}
.note{color:#4b5563;font-size:.88rem}figure{margin:1rem 0 2rem}
figure img{max-width:100%;border:1px solid #e5e7eb}figcaption{font-size:.85rem;color:#4b5563}
.claims{background:#f8fafc;border-left:4px solid #2b5797;padding:.4rem 1rem}
code{background:#eef2f7;padding:0 .25rem;border-radius:3px}
#ranking-table td:nth-child(2){text-align:left}.claims table{font-size:.8rem;width:100%}
.claims td,.claims th{white-space:normal;text-align:left;overflow-wrap:anywhere}
.scroll{overflow-x:auto}
"""


#: Alignment codes of :attr:`Table.align`: left (the default) and right.
ALIGNMENTS = {"l": "---|", "r": "---:|"}


@dataclass(frozen=True)
class Table:
    """A table: a header row, body rows of cells (inline Markdown) and each column's alignment.

    Attributes:
        headers: The header cells, one per column.
        rows: The body rows; each has ``len(headers)`` cells.
        align: One code per column, ``"l"`` (left) or ``"r"`` (right); empty: all left.

    Raises:
        ValueError: A row or ``align`` does not have one entry per column, or a code is unknown.
    """

    headers: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    align: str = ""

    def __init__(
        self, headers: Sequence[str], rows: Sequence[Sequence[str]], align: str = ""
    ) -> None:
        width = len(headers)
        bad = [i for i, row in enumerate(rows) if len(row) != width]
        if bad:
            raise ValueError(f"Table row {bad[0]} has {len(rows[bad[0]])} cells, not {width}")
        if align and (len(align) != width or set(align) - set(ALIGNMENTS)):
            raise ValueError(f"Table align {align!r}: one of {sorted(ALIGNMENTS)} per column")
        object.__setattr__(self, "headers", tuple(headers))
        object.__setattr__(self, "rows", tuple(tuple(row) for row in rows))
        object.__setattr__(self, "align", align or "l" * width)


def table_markdown(table: Table) -> list[str]:
    """The Markdown lines of ``table``: ``| a | b |``, ``|---|---:|``, then one line per row."""
    return [
        _table_line(table.headers),
        "|" + "".join(ALIGNMENTS[code] for code in table.align),
        *(_table_line(row) for row in table.rows),
    ]


def _table_line(cells: Sequence[str]) -> str:
    return "| " + " | ".join(cells) + " |"


def table_html(table: Table) -> str:
    """The HTML of ``table``: a ``<th>`` row, then ``<td>`` rows, each cell inline-rendered.

    The same markup :func:`markdown_to_html` gives the table's Markdown, without re-parsing it
    (a cell holding ``|`` stays one cell).
    """
    rows = [("th", table.headers), *(("td", row) for row in table.rows)]
    cells = (
        "<tr>" + "".join(f"<{tag}>{_inline(c.strip())}</{tag}>" for c in row) for tag, row in rows
    )
    return "<table>" + "".join(cells) + "</table>"


def _inline(text: str) -> str:
    """Escape, then render `` `code` ``, ``$math$`` (as code), ``**bold**`` and ``*em*``."""
    parts = re.split(r"(``[^`]+``|`[^`]+`|\$[^$]+\$)", text)
    out = []
    for part in parts:
        if len(part) > 1 and part[0] == part[-1] and part[0] in "`$":
            out.append(f"<code>{escape(part.strip('`$'))}</code>")
            continue
        piece = escape(part)
        piece = re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", piece)
        out.append(re.sub(r"(?<![\w*])\*(\S.*?)\*(?![\w*])", r"<em>\1</em>", piece))
    return "".join(out)


def heading_html(level: int, text: str) -> str:
    """A Markdown heading of ``level`` (1 = ``#``) as HTML: ``<h(level + 2)>``, at most ``<h6>``."""
    tag = min(level + 2, 6)
    return f"<h{tag}>{_inline(text)}</h{tag}>"


def markdown_to_html(markdown: str) -> str:
    """Minimal Markdown → HTML for claims files: headings, tables, lists, paragraphs."""
    out: list[str] = []
    lines = markdown.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i].rstrip()
        if not line.strip():
            i += 1
            continue
        heading = re.match(r"^(#{1,6}) (.*)", line)
        if heading:
            out.append(heading_html(len(heading.group(1)), heading.group(2)))
            i += 1
        elif line.lstrip().startswith("|"):
            block = []
            while i < len(lines) and lines[i].lstrip().startswith("|"):
                block.append(lines[i].strip().strip("|"))
                i += 1
            cells = [[c.strip() for c in b.split("|")] for b in block]
            body = [c for c in cells if not all(re.fullmatch(r":?-+:?", x) for x in c if x)]
            parts = ["<table>"]
            for r, row in enumerate(body):
                tag = "th" if r == 0 else "td"
                parts.append("<tr>" + "".join(f"<{tag}>{_inline(c)}</{tag}>" for c in row))
            out.append("".join(parts) + "</table>")
        elif re.match(r"^\s*[-*] ", line):
            items: list[str] = []
            while i < len(lines) and lines[i].strip():
                if re.match(r"^\s*[-*] ", lines[i]):
                    items.append(re.sub(r"^\s*[-*] ", "", lines[i]).strip())
                else:  # continuation line of the current item
                    items[-1] += " " + lines[i].strip()
                i += 1
            items = [f"<li>{_inline(text)}</li>" for text in items]
            out.append("<ul>" + "".join(items) + "</ul>")
        else:
            paragraph = []
            while (
                i < len(lines) and lines[i].strip() and not re.match(r"^(#|\||\s*[-*] )", lines[i])
            ):
                paragraph.append(lines[i].strip())
                i += 1
            out.append(f"<p>{_inline(' '.join(paragraph))}</p>")
    return "\n".join(out)
