"""``decide: {budget_tasks, batch}``: studies that run batches until each kind is decided."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from otmm_qp.cli import main
from otmm_qp.studies import decide as decide_module
from otmm_qp.studies.decide import DecideRule, Decision, decided, run_decided, split
from otmm_qp.studies.storage import read_episodes
from tests.cli_errors import refusal_text


def _row(name: str, index: int, success: bool) -> dict[str, Any]:
    return {
        "controller": name,
        "robot": "r",
        "generator": "g",
        "generator_params": "{}",
        "task_index": index,
        "loop_mode": "clik",
        "success": success,
    }


def test_decided_needs_a_row_better_than_every_other() -> None:
    # exact McNemar, 2 rows: all-discordant needs 6 tasks (2/64 = 0.031 < 0.05; 2/32 is not)
    six = [_row("a", i, True) for i in range(6)] + [_row("b", i, False) for i in range(6)]
    assert decided(six) == "a"
    five = [_row("a", i, True) for i in range(5)] + [_row("b", i, False) for i in range(5)]
    assert decided(five) is None
    # a third row as good as a: nobody beats every other
    three = six + [_row("c", i, True) for i in range(6)]
    assert decided(three) is None


@pytest.mark.parametrize(
    ("total", "weights"), [(1, [3, 1]), (6, [400, 200, 150, 150, 100]), (41, [1, 1, 1]), (7, [5])]
)
def test_split_sums_and_follows_the_weights(total: int, weights: list[int]) -> None:
    counts = split(total, weights)
    assert sum(counts) == total
    assert all(c >= 1 for c in counts[: min(total, len(weights))])
    rest = total - min(total, len(weights))
    for count, weight in zip(counts, weights, strict=True):
        assert (
            abs(count - (1 if total >= len(weights) else count) - weight * rest / sum(weights)) < 1
        )


def _judged(picks_by_batch: list[dict[tuple[str, str], str | None]]) -> Any:
    calls = iter(picks_by_batch)

    def judge(out: Path, tasks: int, budget: int) -> Decision:
        return Decision(tasks, budget, next(calls))

    return judge


def test_batches_stop_when_every_kind_is_decided(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    undecided = {("r", "singular crossings"): None, ("r", "beyond-reach motion"): "qp"}
    decided_all = {("r", "singular crossings"): "qp", ("r", "beyond-reach motion"): "qp"}
    monkeypatch.setattr(decide_module, "judge", _judged([undecided, decided_all, decided_all]))
    limits: list[list[int]] = []

    class Config:
        generators = [type("G", (), {"count": 3})(), type("G", (), {"count": 1})()]

    def run_batch(_: Any, batch: int, counts: list[int]) -> bool:
        limits.append(counts)
        return True

    decision = run_decided(Config(), DecideRule(budget_tasks=20, batch=8), tmp_path, run_batch)  # type: ignore[arg-type]
    assert decision.done and decision.tasks == 16
    assert limits == [split(8, [3, 1]), split(16, [3, 1])]  # stopped after batch 2 of 3
    text = (tmp_path / "decision.md").read_text(encoding="utf-8")
    assert "Decided every kind of task after 16 tasks per robot (budget 20)" in text
    assert "**qp** beats every other row on success" in text


def test_budget_spent_is_said(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    undecided = {("r", "singular crossings"): None}
    monkeypatch.setattr(decide_module, "judge", _judged([undecided] * 3))

    class Config:
        generators = [type("G", (), {"count": 1})()]

    batches: list[int] = []
    decision = run_decided(
        Config(),  # type: ignore[arg-type]
        DecideRule(budget_tasks=5, batch=2),
        tmp_path,
        lambda _, batch, counts: batches.append(counts[0]) is None,
    )
    assert batches == [2, 4, 5] and not decision.done
    assert "Budget spent: 5 of 5 tasks per robot run" in (tmp_path / "decision.md").read_text()


STUDY = """\
name: decide-tiny
seed: 3
dt: 0.02
loop_modes: [clik]
duration: {extra: 0.2}
success: {max_position_error: 0.02, max_joint_speed: 10.0}
robots:
  - name: planar2
    robot: {type: planar, link_lengths: [1.0, 0.8]}
generators:
  - {type: near_singular, count: 1, distance: [0.02, 0.1], duration: [1.0, 1.5]}
DECIDE
controllers:
  - name: qp
    backend: {type: qp, solver: daqp, regularization: 1.0e-3}
  - name: sluggish
    backend: {type: dls, damping: 3.0}
"""


def test_a_decide_study_resumes_and_reproduces(tmp_path: Path) -> None:
    config = tmp_path / "d.yaml"
    config.write_text(STUDY.replace("DECIDE", "decide: {budget_tasks: 4, batch: 2}"))
    tables = []
    for name in ("a", "b", "a"):  # a, then b from scratch, then a again (resumed)
        out = tmp_path / name
        argv = ["study", str(config), "--out", str(out), "--workers", "1", "--quiet"]
        assert main([*argv, "--no-report"]) == 0
        table = read_episodes(out)
        assert table is not None
        tables.append(table)
    keys = [sorted(t.column("episode_key").to_pylist()) for t in tables]
    assert keys[0] == keys[1] == keys[2] and len(keys[0]) == 4 * 3  # 4 tasks x (2 rows + ref)
    columns = ("episode_key", "max_error", "max_joint_speed", "success")

    def values(table: Any) -> list[tuple[Any, ...]]:
        rows = table.select(list(columns)).to_pylist()
        return sorted(tuple(r[c] for c in columns) for r in rows)

    assert values(tables[0]) == values(tables[1]) == values(tables[2])  # bit for bit
    a, b = ((tmp_path / n / "decision.md").read_text() for n in ("a", "b"))
    assert a == b and "Budget spent: 4 of 4" in a


@pytest.mark.parametrize(
    ("block", "message"),
    [
        ("decide: {budget_tasks: 0, batch: 2}", "decide.budget_tasks"),
        ("decide: {budget_tasks: -5, batch: 2}", "decide.budget_tasks"),
        ("decide: {budget_tasks: .nan, batch: 2}", "decide.budget_tasks"),
        ("decide: {budget_tasks: 1.0e+12, batch: 2}", "decide.budget_tasks"),
        ("decide: {budget_tasks: 10, batch: 0}", "decide.batch"),
        ("decide: {budget_tasks: 10}", "decide.batch"),
        ("decide: {budget_tasks: 500000, batch: 10}", "max_tasks"),
        ("decide: {budget_tasks: 10, batch: 2, extra: 1}", "decide.extra"),
    ],
)
def test_bad_decide_blocks_are_one_line_before_compute(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], block: str, message: str
) -> None:
    config = tmp_path / "d.yaml"
    config.write_text(STUDY.replace("DECIDE", block))
    out = tmp_path / "out"
    assert main(["study", str(config), "--out", str(out), "--workers", "1", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert message in refusal_text(err), err  # first line <= 200 characters, details after
    assert not out.exists()
