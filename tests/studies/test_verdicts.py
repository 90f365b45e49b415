"""Typed verdicts (otmm_qp.studies.verdicts): the decision, not its sentence."""

from __future__ import annotations

from pathlib import Path

import pytest
from scipy import stats

from otmm_qp.studies.rows import load_rows
from otmm_qp.studies.verdicts import (
    TaskGroup,
    accuracy_verdict,
    decide_group,
    generator_rates,
    success_summary,
    task_groups,
)
from tests.studies.test_report import _synthetic as _row  # the renderer test's rows


def test_the_pick_its_tie_and_the_closest_beaten_row() -> None:
    rows = [_row("a", i, True) for i in range(30)]
    rows += [_row("b", i, i < 5) for i in range(30)]
    rows += [_row("c", i, i != 0) for i in range(30)]
    verdict = decide_group(TaskGroup("singular crossings", "test tasks", rows))
    assert verdict.outcome == "pick" and verdict.pick == "a" and verdict.tasks == 30
    assert verdict.rates == {"a": 1.0, "b": 5 / 30, "c": 29 / 30}
    assert verdict.not_separated == ("c",) and verdict.beaten == 1
    closest = verdict.closest
    assert closest is not None and closest.name == "b"
    assert (closest.pick_only, closest.other_only) == (25, 0)
    exact = stats.binomtest(25, 25, 0.5).pvalue  # McNemar: 25 discordant pairs, all for a
    assert exact <= closest.p_holm <= 3 * exact  # Holm over the three pairs


def test_no_tasks_one_row_nobody_and_a_tie() -> None:
    assert decide_group(TaskGroup("g", "none", [])).outcome == "no tasks"
    single = decide_group(TaskGroup("g", "one", [_row("a", i, i < 3) for i in range(4)]))
    assert single.outcome == "single" and single.pick == "a" and single.rates == {"a": 0.75}
    zero = [_row(n, i, False) for n in "ab" for i in range(5)]
    assert decide_group(TaskGroup("g", "zero", zero)).outcome == "none succeeds"
    tied = [_row(n, i, i % 2 == 0) for n in "xy" for i in range(10)]
    verdict = decide_group(TaskGroup("g", "tied", tied))
    assert verdict.outcome == "not separated" and verdict.pick is None
    assert {r.rank for r in verdict.ranking} == {1}


def test_groups_and_accuracy_of_a_stored_study(small_study: Path) -> None:
    _, rows = load_rows(small_study)
    groups = task_groups(rows, "planar2")
    assert [g.label for g in groups] == [
        "singular crossings",
        "unachievable (certified)",
        "undecided",
        "limit-bound motion",
    ]
    for group in groups:
        assert all(r["controller"] != "oracle" for r in group.rows)
        verdict = decide_group(group)
        assert set(verdict.rates) <= {"pinv", "dls"}
        if verdict.pick is not None:
            assert verdict.rates[verdict.pick] == max(verdict.rates.values())
    accuracy = accuracy_verdict(rows, "planar2")
    assert accuracy.relative and accuracy.top and set(accuracy.top) <= {"pinv", "dls"}
    best = min(m.value for m in accuracy.medians.values())
    assert any(accuracy.medians[name].value == best for name in accuracy.top)


def test_success_summary_and_generator_rates(small_study: Path) -> None:
    _, rows = load_rows(small_study)
    lines = success_summary(rows, "planar2", ["max_error"])
    assert [line.controller for line in lines] == ["pinv", "dls", "oracle"]
    for line in lines:
        own = [r for r in rows.rows if r["controller"] == line.controller]
        assert line.episodes == len(own) == 3
        if line.controller == "oracle":
            assert line.rate is None
            continue
        wins = sum(bool(r["success"]) for r in own)
        assert line.rate == wins / 3
        ci = stats.binomtest(wins, 3).proportion_ci(method="wilson")
        assert (line.low, line.high) == pytest.approx((ci.low, ci.high), abs=1e-12)
        (median,) = line.medians
        assert median.low <= median.value <= median.high
    groups, table = generator_rates(rows)
    assert groups == [("planar2", "near_singular"), ("planar2", "beyond_reach")]
    assert set(table) == {"pinv", "dls"} and all(len(cells) == 2 for cells in table.values())
