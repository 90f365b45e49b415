"""docs/architecture.md's Studies section: its new-analysis example runs, its paths exist."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from otmm_qp.studies import load

DOC = Path(__file__).resolve().parents[2] / "docs" / "architecture.md"


def _section() -> str:
    text = DOC.read_text(encoding="utf-8")
    start = text.index("## Studies")
    end = text.find("\n## ", start + 1)
    return text[start:] if end < 0 else text[start:end]


def test_the_new_analysis_example_runs_on_a_study(small_study: Path) -> None:
    block = re.search(r"```python\n(.*?)```", _section(), re.S)
    assert block is not None
    namespace: dict[str, Any] = {}
    exec(block.group(1), namespace)  # the doc's own example
    counts = namespace["success_by_generator"](small_study)
    rows = [r for r in load(small_study).to_pylist() if r["controller"] != "oracle"]
    assert sum(total for _, total in counts.values()) == len(rows)
    assert sum(wins for wins, _ in counts.values()) == sum(r["success"] for r in rows)
    assert {c for c, _ in counts} == {"pinv", "dls"}


def test_every_path_the_section_names_exists() -> None:
    root = DOC.parents[1]
    paths = set(re.findall(r"`((?:otmm_qp|tests|docs)/[\w/.]+\.(?:py|md))`", _section()))
    assert len(paths) > 5
    assert sorted(p for p in paths if not (root / p).is_file()) == []
