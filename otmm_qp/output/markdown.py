"""Minimal Markdown → HTML (headings, tables, lists, paragraphs) for claims and study reports.

A leaf of the output layer: the run report and the study report both import it, so neither
imports the other.
"""

from __future__ import annotations

import re

from otmm_qp.output.escape import escape


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
            level = min(len(heading.group(1)) + 2, 6)
            out.append(f"<h{level}>{_inline(heading.group(2))}</h{level}>")
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
