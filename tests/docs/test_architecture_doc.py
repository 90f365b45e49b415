"""docs/architecture.md's Harness section: its worked example is the code's, its paths exist."""

from __future__ import annotations

import re
from pathlib import Path

from otmm_qp.metrics import METRIC_NAMES, METRICS, Metric

DOC = Path(__file__).resolve().parents[2] / "docs" / "architecture.md"


def _harness() -> str:
    text = DOC.read_text(encoding="utf-8")
    start = text.index("## Harness")
    end = text.find("\n## ", start + 1)
    return text[start:] if end < 0 else text[start:end]


def test_the_worked_metric_row_is_the_tables_row() -> None:
    block = re.search(r"```python\n(Metric\(.*?\))\n```", _harness(), re.S)
    assert block is not None
    row = eval(block.group(1), {"Metric": Metric})  # the doc's own snippet
    assert row in METRICS and row.name in METRIC_NAMES


def test_every_path_the_section_names_exists() -> None:
    root = DOC.parents[1]
    paths = set(re.findall(r"`((?:otmm_qp|tests|docs)/[\w/.]+\.(?:py|md))`", _harness()))
    assert len(paths) > 10
    missing = sorted(p for p in paths if not (root / p).is_file())
    assert missing == []
