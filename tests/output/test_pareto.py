"""The Pareto comparison: dominance, fronts, blown-up runs, files written, bad input."""

from __future__ import annotations

from pathlib import Path

import pytest

from otmm_qp.cli import main as cli
from otmm_qp.exceptions import OtmmError
from otmm_qp.output.pareto import (
    Entry,
    dominates,
    pareto_front,
    pareto_markdown,
    read_summary,
)

HEADER = (
    "experiment,loop_mode,controller,max_error_window,max_joint_speed,max_jump,blow_up,completed"
)


def test_dominance_and_front() -> None:
    assert dominates((1, 1, 1), (1, 2, 1)) and not dominates((1, 1, 1), (1, 1, 1))
    assert not dominates((0, 2, 1), (1, 1, 1))
    entries = [
        Entry("s", "a", (1.0, 1.0, 1.0), True),
        Entry("s", "b", (2.0, 2.0, 2.0), True),  # dominated by a
        Entry("s", "c", (0.5, 3.0, 1.0), True),  # trade-off: on the front
        Entry("s", "d", (0.1, 0.1, 0.1), False),  # blew up: never on the front
    ]
    assert [e.controller for e in pareto_front(entries)] == ["a", "c"]
    text = pareto_markdown(entries)
    assert "| s | c (0.5) | a (1) | a (1) | a, c |" in text


def test_reads_summaries_and_writes_inside_out(tmp_path: Path) -> None:
    results = tmp_path / "run"
    results.mkdir()
    (results / "summary.csv").write_text(
        HEADER + "\nE1,clik,x,1e-3,0.5,0.1,False,True\nE1,clik,y,1e-4,200,150,True,True\n",
        encoding="utf-8",
    )
    entries = read_summary(results / "summary.csv")
    assert [e.valid for e in entries] == [True, False]
    out = tmp_path / "out"
    assert cli(["pareto", str(results), "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["pareto.md", "pareto.png"]
    assert "| E1/clik | x (0.001) | x (0.5) | x (0.1) | x |" in (out / "pareto.md").read_text()


def test_missing_summary_is_a_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert cli(["pareto", str(tmp_path / "nope"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("otmm-qp: error:") and "no summary.csv" in err and "\n" not in err
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "summary.csv").write_text("experiment,loop_mode\nE1,clik\n", encoding="utf-8")
    with pytest.raises(OtmmError, match="missing column"):
        read_summary(bad / "summary.csv")
