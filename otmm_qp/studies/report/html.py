"""The report's self-contained HTML page (figures embedded as base64)."""

from __future__ import annotations

import base64
from collections.abc import Sequence
from pathlib import Path

from otmm_qp.output.escape import escape
from otmm_qp.paths import ensure_inside
from otmm_qp.studies.document import Item, to_html
from otmm_qp.studies.schema import StudyConfig

#: The run report's stylesheet, plus the study report's verdict box.
_STUDY_CSS = ".verdict{background:#f8fafc;border-left:4px solid #2b5797;padding:.2rem 1rem}"


def render_html(config: StudyConfig, items: Sequence[Item], out: Path) -> str:
    """The self-contained HTML page of the report's items, figures embedded as base64.

    Every name (controllers, robots, generators) reaches the page through
    :func:`otmm_qp.output.escape.escape` (in :func:`otmm_qp.output.markdown.markdown_to_html`).
    """
    from otmm_qp.output.markdown import REPORT_CSS

    return to_html(
        items,
        f"Study {config.name}",
        REPORT_CSS + _STUDY_CSS,
        lambda figure: _figure_html(out, figure.path, figure.caption),
    )


def _figure_html(out: Path, relative: str, caption: str) -> str:
    path = ensure_inside(out, out / relative)
    if not path.is_file():
        return ""
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    label = escape(caption, "attr")
    return (
        f'<figure><img alt="{label}" src="data:image/png;base64,{data}">'
        f"<figcaption>{label}</figcaption></figure>"
    )
