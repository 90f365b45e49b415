"""The study report as a small document model, rendered once to Markdown and once to HTML.

A document is a list of items: Markdown text lines (paragraphs, lists), a :class:`Table`
(rendered by :mod:`otmm_qp.output.markdown`, never re-parsed from Markdown), a
:class:`Heading` (a ``box`` heading puts the text up to the next heading in a verdict box)
and a :class:`Figure`. :func:`to_markdown` writes ``study_report.md``; :func:`to_html`
renders the same items for ``study_report.html`` (figures embedded by the caller's
``figure`` function, the page from a Jinja2 template) — no pattern matching over Markdown.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import jinja2

from otmm_qp.output.escape import escape
from otmm_qp.output.markdown import (
    Table,
    heading_html,
    markdown_to_html,
    table_html,
    table_markdown,
)

__all__ = ["Figure", "Heading", "Item", "Table", "to_html", "to_markdown"]


@dataclass(frozen=True)
class Heading:
    """A section heading.

    Attributes:
        level: 1 (``#``, the title) to 6.
        text: The heading (inline Markdown).
        box: It and the text after it, up to the next heading, are a verdict box.
    """

    level: int
    text: str
    box: bool = False

    def markdown(self) -> str:
        """``## text``."""
        return f"{'#' * self.level} {self.text}"


@dataclass(frozen=True)
class Figure:
    """A figure of the study folder.

    Attributes:
        path: Its path relative to the study folder (``figures/...png``).
        caption: Its caption.
    """

    path: str
    caption: str

    def markdown(self) -> str:
        """``![caption](path)``."""
        return f"![{self.caption}]({self.path})"


#: One item of a document.
Item = str | Heading | Figure | Table

_PAGE = jinja2.Environment(autoescape=False, keep_trailing_newline=True).from_string(
    '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
    "<title>{{ title }}</title><style>{{ css }}</style></head><body>\n"
    "{{ body }}\n</body></html>\n"
)


def to_markdown(items: Sequence[Item]) -> str:
    """The Markdown of a document (one line per text item, a table's lines in a block)."""
    return "\n".join(_markdown(item) for item in items)


def _markdown(item: Item) -> str:
    if isinstance(item, str):
        return item
    if isinstance(item, Table):
        return "\n".join(table_markdown(item))
    return item.markdown()


def to_html(items: Sequence[Item], title: str, css: str, figure: Callable[[Figure], str]) -> str:
    """The self-contained HTML page of a document.

    Args:
        items: The document.
        title: The page title (escaped here).
        css: The style sheet.
        figure: The HTML of a figure (e.g. embedded as base64), or ``""`` to leave it out.
    """
    parts: list[str] = []
    text: list[str | Table] = []  # the run of text lines and tables up to the next heading
    boxed = False
    if items and items[-1] == "":  # the Markdown's final newline, not an empty paragraph
        items = items[:-1]

    def flush() -> None:
        if text:
            body = _run_html(text)
            parts.append(f'<div class="verdict">{body}</div>' if boxed else body)
            text.clear()

    for item in items:
        if isinstance(item, (str, Table)):
            text.append(item)
            continue
        flush()
        if isinstance(item, Heading):
            boxed = item.box
            html = heading_html(item.level, item.text)
            parts.append(f'<div class="verdict">{html}</div>' if boxed else html)
        else:
            parts.append(figure(item))
    flush()
    return _PAGE.render(title=escape(title), css=css, body="\n".join(parts))


def _run_html(run: Sequence[str | Table]) -> str:
    """The HTML of a run of text lines and tables, up to the next heading or figure.

    Each stretch of lines goes through :func:`markdown_to_html`, each table through
    :func:`table_html`; the blocks are joined by a newline, as :func:`markdown_to_html` joins
    its own (so a table reads as it did when it was Markdown lines of the run).
    """
    pieces: list[str] = []
    lines: list[str] = []
    for entry in [*run, None]:
        if isinstance(entry, str):
            lines.append(entry)
            continue
        html = markdown_to_html("\n".join(lines))
        lines.clear()
        if html:
            pieces.append(html)
        if entry is not None:
            pieces.append(table_html(entry))
    return "\n".join(pieces)
