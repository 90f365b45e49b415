"""``decide: {budget_tasks, batch}``: studies that run batches until the arm is decided."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from scipy.integrate import quad
from scipy.stats import beta

from otmm_qp.cli import main
from otmm_qp.studies import decide as decide_module
from otmm_qp.studies.decide import (
    BatchStatus,
    DecideRule,
    Decision,
    decided,
    run_decided,
    split,
)
from otmm_qp.studies.sequential import PRIOR, SequentialVerdict
from otmm_qp.studies.sequential import pick as sequential_pick
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


def _quadrature_e(wins: int, discordant: int) -> float:
    """``E_{A>B}`` by numerical integration of the one-sided Beta mixture (independent)."""
    a = PRIOR

    def integrand(theta: float) -> float:
        ratio = theta**wins * (1 - theta) ** (discordant - wins) / 0.5**discordant
        return 2.0 * ratio * float(beta.pdf(theta, a, a))

    return float(quad(integrand, 0.5, 1.0)[0])


def test_decided_needs_a_row_better_than_every_other() -> None:
    # 2 rows, every task discordant for a: decided at the first n whose e-value reaches 2/α
    n = next(n for n in range(1, 200) if _quadrature_e(n, n) >= 2 / 0.05)
    rows = [_row("a", i, True) for i in range(n)] + [_row("b", i, False) for i in range(n)]
    assert decided(rows) == "a"
    fewer = [r for r in rows if r["task_index"] < n - 1]
    assert decided(fewer) is None
    # a third row as good as a: nobody beats every other
    assert decided(rows + [_row("c", i, True) for i in range(n)]) is None


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


@pytest.mark.parametrize("weights", [[100, 200, 150, 50, 70, 30], [3, 1], [5], [1, 1, 1]])
def test_the_last_batch_runs_the_whole_budget(weights: list[int]) -> None:
    # the loop's weights are budget_config's counts: the last batch must be all of them
    for budget in (7, 60, 150, 600):
        counts = split(budget, weights)
        assert split(budget, counts) == counts


def _verdict(pick: str | None) -> SequentialVerdict:
    """qp alone succeeding on 60 tasks (decided) or on 3 (undecided)."""
    n = 60 if pick else 3
    return sequential_pick(
        {"qp": dict.fromkeys(range(n), True), "dls": dict.fromkeys(range(n), False)}
    )


def _judged(picks_by_batch: list[dict[str, str | None]]) -> Any:
    calls = iter(picks_by_batch)

    def judge(out: Path, tasks: int, budget: int) -> Decision:
        picks = next(calls)
        return Decision(tasks, budget, {robot: _verdict(p) for robot, p in picks.items()})

    return judge


class _Config:
    generators = [type("G", (), {"count": 3})(), type("G", (), {"count": 1})()]


def test_batches_stop_when_every_arm_is_decided(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    undecided = {"r": None, "s": "qp"}
    decided_all = {"r": "qp", "s": "qp"}
    monkeypatch.setattr(decide_module, "judge", _judged([undecided, decided_all, decided_all]))
    limits: list[list[int]] = []

    def run_batch(_: Any, batch: int, counts: list[int]) -> BatchStatus:
        limits.append(counts)
        return "ok"

    decision = run_decided(_Config(), DecideRule(budget_tasks=20, batch=8), tmp_path, run_batch)  # type: ignore[arg-type]
    assert decision.done and decision.tasks == 16 and decision.stop == "decided"
    assert limits == [split(8, [3, 1]), split(16, [3, 1])]  # stopped after batch 2 of 3
    text = (tmp_path / "decision.md").read_text(encoding="utf-8")
    assert "Decided after 16 tasks per robot (budget 20)" in text
    assert "run **qp**" in text and "anytime-valid" in text


def _group() -> SequentialVerdict:
    """a and b beat c; they differ on one task of 80: a group, not a pick."""
    a = dict.fromkeys(range(80), True)
    return sequential_pick({"a": a, "b": {t: t != 3 for t in a}, "c": {t: t < 20 for t in a}})


@pytest.mark.parametrize(("budget", "batches"), [(160, 1), (99_999, 3)])
def test_a_group_the_budget_cannot_split_stops_the_study(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, budget: int, batches: int
) -> None:
    def judge(out: Path, tasks: int, total: int) -> Decision:
        return Decision(tasks, total, {"r": _group()})

    monkeypatch.setattr(decide_module, "judge", judge)
    ran: list[int] = []

    def run_batch(_: Any, batch: int, counts: list[int]) -> BatchStatus:
        ran.append(batch)
        return "ok"

    rule = DecideRule(budget_tasks=budget, batch=budget // 3 if batches == 3 else 80)
    decision = run_decided(_Config(), rule, tmp_path, run_batch)  # type: ignore[arg-type]
    needed = decision.needed("r")  # a vs b, 1 to 0 in 80 tasks: about 1,300 tasks to split
    assert _group().group == ("a", "b") and needed is not None and 160 < needed < 99_999
    if needed > budget:  # not expected to separate within the budget: stop, name the group
        assert ran == [1] and decision.stop == "group"
        text = (tmp_path / "decision.md").read_text()
        assert "Stopped after 80 tasks" in text and "undecided between a, b" in text
    else:  # the budget may split them: go on
        assert len(ran) == batches and decision.stop == "budget"


def test_budget_spent_is_said(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(decide_module, "judge", _judged([{"r": None}] * 3))
    batches: list[int] = []

    def run_batch(_: Any, batch: int, counts: list[int]) -> BatchStatus:
        batches.append(sum(counts))
        return "ok"

    decision = run_decided(_Config(), DecideRule(budget_tasks=5, batch=2), tmp_path, run_batch)  # type: ignore[arg-type]
    assert batches == [2, 4, 5] and not decision.done and decision.stop == "budget"
    text = (tmp_path / "decision.md").read_text()
    assert "Budget spent: 5 of 5 tasks per robot run" in text and "**" not in text.split("\n")[2]


def test_an_interrupt_is_recorded_as_an_interrupt(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(decide_module, "judge", _judged([{"r": None}] * 3))
    statuses = iter(["ok", "interrupted"])

    def run_batch(_: Any, batch: int, counts: list[int]) -> BatchStatus:
        return next(statuses)  # type: ignore[return-value]

    decision = run_decided(_Config(), DecideRule(budget_tasks=6, batch=2), tmp_path, run_batch)  # type: ignore[arg-type]
    text = (tmp_path / "decision.md").read_text()
    assert decision.stop == "interrupted" and "Interrupted after 2 of 6" in text
    assert "Budget spent" not in text


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


def _parts(out: Path) -> set[str]:
    return {p.name for p in (out / "episodes").glob("part-*.parquet")}


def _part_keys(out: Path, names: set[str]) -> set[str]:
    import pyarrow.parquet as pq

    keys: set[str] = set()
    for name in names:
        keys.update(pq.read_table(out / "episodes" / name).column("episode_key").to_pylist())
    return keys


def test_raising_the_budget_reruns_no_stored_episode(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "d.yaml"
    out = tmp_path / "out"
    argv = ["study", str(config), "--out", str(out), "--workers", "1", "--quiet", "--no-report"]
    config.write_text(STUDY.replace("DECIDE", "decide: {budget_tasks: 2, batch: 2}"))
    assert main(argv) == 0
    first = _parts(out)
    stored = _part_keys(out, first)
    assert len(stored) == 2 * 3  # 2 tasks x (2 rows + reference)
    config.write_text(STUDY.replace("DECIDE", "decide: {budget_tasks: 4, batch: 1}"))
    capsys.readouterr()
    assert main(argv) == 0
    assert "6 episodes run (0 failed), 6 already stored, of 12" in capsys.readouterr().out
    new = _parts(out) - first
    assert first <= _parts(out) and not _part_keys(out, new) & stored  # nothing stored rerun
    table = read_episodes(out)
    assert table is not None and len(table) == 4 * 3  # both runs' episodes are the study's
    assert "of 4 tasks per robot" in (out / "decision.md").read_text()
    config.write_text(STUDY.replace("DECIDE", "decide: {budget_tasks: 3, batch: 3}"))
    before = _parts(out)
    assert main(argv) == 0
    assert _parts(out) == before  # a lower budget judges the stored prefix, runs nothing
    assert "0 episodes run (0 failed), 9 already stored, of 9" in capsys.readouterr().out
    assert "3 of 3 tasks per robot" in (out / "decision.md").read_text()


def test_a_task_that_cannot_be_generated_is_a_row_and_the_study_goes_on(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from otmm_qp.scenarios.generator import TaskGenerationError
    from otmm_qp.studies.task import StudyTask

    build = StudyTask.build

    def flaky(self: StudyTask, config: Any, cache: Any = None) -> Any:
        if self.index == 1:
            raise TaskGenerationError("near_singular", "planar2", "no start pose (test)")
        return build(self, config, cache)

    monkeypatch.setattr(StudyTask, "build", flaky)
    config = tmp_path / "d.yaml"
    config.write_text(STUDY.replace("DECIDE", "decide: {budget_tasks: 4, batch: 2}"))
    out = tmp_path / "out"
    main(["study", str(config), "--out", str(out), "--workers", "1", "--quiet", "--no-report"])
    table = read_episodes(out)
    assert table is not None and len(table) == 4 * 3  # the batch after the failure ran too
    messages = [m for m in table.column("error_message").to_pylist() if m]
    # task 1's rows, each with its reason
    assert len(messages) == 3 and all("no start pose (test)" in m for m in messages)
    text = (out / "decision.md").read_text()
    assert "Budget spent: 4 of 4" in text and "1 task(s) could not be generated" in text


def test_a_decide_folder_stored_before_issue_36_is_still_read(tmp_path: Path) -> None:
    import json

    from otmm_qp.studies.storage import StudyDirectoryError, read_study_folder, study_id

    config = tmp_path / "d.yaml"
    config.write_text(STUDY.replace("DECIDE", "decide: {budget_tasks: 2, batch: 2}"))
    out = tmp_path / "out"
    argv = ["study", str(config), "--out", str(out), "--workers", "1", "--quiet", "--no-report"]
    assert main(argv) == 0
    marker = json.loads((out / "study.json").read_text())
    assert marker["study_id"] != study_id(marker["config"], whole=True)  # the id changed
    marker["study_id"] = study_id(marker["config"], whole=True)  # as such a folder holds it
    (out / "study.json").write_text(json.dumps(marker))
    read_study_folder(out)  # the former id is accepted, an edited config still is not
    marker["config"]["seed"] = 4
    (out / "study.json").write_text(json.dumps(marker))
    with pytest.raises(StudyDirectoryError, match="does not hash to its study_id"):
        read_study_folder(out)
