"""Issue 37: ``study verdict --limit-keeping`` leaves out (and names) the rows that break limits."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from otmm_qp.cli import main
from otmm_qp.studies.limit_keeping import limit_breaks
from otmm_qp.studies.rows import load_rows

#: Two tasks, three rows; a speed criterion so tight that a moving row breaks it.
STUDY = {
    "name": "limit-keeping-tiny",
    "seed": 5,
    "dt": 0.05,
    "duration": {"extra": 0.1},
    "success": {"max_joint_speed": 0.05},
    "robots": [{"name": "planar2", "robot": {"type": "planar", "link_lengths": [1.0, 0.8]}}],
    "generators": [{"type": "near_singular", "count": 2, "duration": [0.5, 0.6]}],
    "controllers": [
        {"name": "dls", "backend": {"type": "dls", "damping": 0.05}},
        {"name": "pinv", "backend": {"type": "pinv"}},
        {"name": "qp", "backend": {"type": "qp"}},
    ],
}


def test_limit_keeping_drops_every_other_row_that_breaks_a_limit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(STUDY))
    out = tmp_path / "out"
    args = ["study", str(path), "--out", str(out), "--workers", "1", "--quiet", "--no-report"]
    assert main(args) == 0
    rows = load_rows(out)[1]
    broken = {name: limit_breaks(rows.rows, name) for name in rows.controllers()}
    breakers = {name for name, (count, _) in broken.items() if count and name != "qp"}
    assert breakers  # the tight speed criterion makes at least one other row break it
    capsys.readouterr()
    assert main(["study", "verdict", str(out), "--ours", "qp", "--kinds", "--limit-keeping"]) == 0
    text = capsys.readouterr().out
    line = next(x for x in text.splitlines() if x.startswith("Limit-keeping rows only"))
    for name in breakers:
        count, total = broken[name]
        assert f"{name} (limits broken on {count} of {total} tasks)" in line
    table = [x for x in text.splitlines() if x.startswith("| ") and "task kind" not in x]
    for name in breakers:
        assert all(f" {name} (" not in x for x in table)
    assert main(["study", "verdict", str(out), "--ours", "qp", "--kinds"]) == 0
    assert "Limit-keeping rows only" not in capsys.readouterr().out
