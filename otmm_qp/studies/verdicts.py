"""A study's verdicts as typed results: the kinds of task, whom to pick for each, the most accurate.

The study report renders these objects (:mod:`otmm_qp.studies.report`); the analyses
(``study verdict --kinds``, ``study tradeoff --group-by kind``) group tasks the same way
through :func:`task_groups`. Nothing here formats text.

* :func:`task_groups`: singular crossings, beyond-reach and limit-bound tasks of a robot,
  chosen from the reference (or by generator without one).
* :func:`decide_group` → :class:`GroupVerdict`: success rates, the ranking by the exact
  McNemar test (Holm), the pick, the rows not separated from it and the closest beaten one
  with its paired evidence.
* :func:`accuracy_verdict` → :class:`AccuracyVerdict`: the rows not beaten in any paired
  Wilcoxon test of the headline accuracy, with their median intervals.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from otmm_qp.exceptions import ConfigError
from otmm_qp.metrics.table import STUDY_OBJECTIVES
from otmm_qp.studies.columns import number
from otmm_qp.studies.criteria import is_achievable
from otmm_qp.studies.fronts import GroupFront, group_fronts
from otmm_qp.studies.limit_keeping import limit_breaks
from otmm_qp.studies.oracle import REFERENCE_NAME
from otmm_qp.studies.rows import RELATIVE_ERROR, Rows, is_reference, task_key, task_of
from otmm_qp.studies.statistics import (
    ALPHA,
    Interval,
    PairedRates,
    PairedResult,
    Ranked,
    binned_medians,
    bootstrap_interval,
    paired_comparisons,
    paired_ranking,
    paired_success,
    wilson_interval,
)

#: Bootstrap resamples of every interval (printed digits follow their Monte-Carlo error).
RESAMPLES = 2000
#: Bins of σ_min at closest approach (log-spaced edges).
SIGMA_BINS = 6
__all__ = ["ALPHA", "RESAMPLES", "SIGMA_BINS"]

#: What a group's verdict says: no tasks, one controller only, nobody succeeds, no paired
#: test separates the controllers, or a pick.
Outcome = Literal["no tasks", "single", "none succeeds", "not separated", "pick"]


#: Labels of the kinds of task the reference's bracket decides (see :func:`task_groups`).
UNACHIEVABLE = "unachievable (certified)"
UNDECIDED = "undecided"

#: The reference's labels (``reference.status``), in the order the bracket table counts them.
BRACKET_LABELS = ("achievable", "unachievable", "undecided", "failed")


@dataclass(frozen=True)
class TaskGroup:
    """A kind of motion a verdict is given for: a label, how its tasks are chosen, its rows."""

    label: str
    reading: str
    rows: list[dict[str, Any]]


def _known(value: Any) -> bool:
    return value is not None and not (isinstance(value, float) and math.isnan(value))


def _flag(row: dict[str, Any], name: str) -> bool:
    value = row.get(name)
    return _known(value) and bool(value)


def task_groups(rows: Rows, robot: str) -> list[TaskGroup]:
    """The kinds of task of ``robot``'s competitor rows (the one place their labels are set).

    With a reference: singular crossings (``reference.near_singular`` and achievable),
    *unachievable (certified)* and *undecided* (``reference.status``: the bracket's labels,
    :func:`otmm_qp.reference.solve.solve_reference`; a stored row of an older study that is
    not achievable and not certified counts as undecided), limit-bound
    (``reference.touches_position_limit``); without one, by generator (``near_singular`` and
    ``joint_path``; ``beyond_reach``; limit-bound tasks cannot be told).
    """
    own = [r for r in rows.select(robot=robot) if not is_reference(r)]
    if rows.has_reference:
        return [
            TaskGroup(
                "singular crossings",
                "tasks whose reference passes near a singularity (σ_min < σ_S) and is achievable",
                [
                    r
                    for r in own
                    if _flag(r, "reference.near_singular") and _flag(r, "reference.achievable")
                ],
            ),
            TaskGroup(
                UNACHIEVABLE,
                "tasks whose certified lower bound exceeds a tolerance (judged by the graceful "
                "criteria)",
                [r for r in own if r.get("reference.status") == "unachievable"],
            ),
            TaskGroup(
                UNDECIDED,
                "tasks no path was found to meet and no bound rules out (judged by the "
                "graceful criteria)",
                [
                    r
                    for r in own
                    if not is_achievable(r) and r.get("reference.status") != "unachievable"
                ],
            ),
            TaskGroup(
                "limit-bound motion",
                "tasks whose reference touches a position limit",
                [r for r in own if _flag(r, "reference.touches_position_limit")],
            ),
        ]
    return [
        TaskGroup(
            "singular crossings",
            "generators near_singular and joint_path (no reference stored)",
            [r for r in own if r["generator"] in ("near_singular", "joint_path")],
        ),
        TaskGroup(
            "beyond-reach motion",
            "generator beyond_reach (no reference stored)",
            [r for r in own if r["generator"] == "beyond_reach"],
        ),
        TaskGroup(
            "limit-bound motion",
            "needs the offline reference (which tasks touch a limit); none stored",
            [],
        ),
    ]


@dataclass(frozen=True)
class BracketRow:
    """The reference's bracket over one kind of task.

    Attributes:
        kind: The kind of task (a :class:`TaskGroup` label, or ``"all tasks"``).
        tasks: Tasks of that kind with a stored reference.
        counts: ``reference.status`` counts, in :data:`BRACKET_LABELS` order.
        median_gap: Median of ``reference.upper − reference.lower`` [tolerances] (NaN: none).
        p90_gap: Its 90th percentile [tolerances] (NaN: none).
        unpassed: Tasks no known path passes: neither a controller row nor the reference's
            own row succeeds.
    """

    kind: str
    tasks: int
    counts: tuple[int, ...]
    median_gap: float
    p90_gap: float
    unpassed: int = 0


def bracket_summary(rows: Rows, robot: str) -> list[BracketRow]:
    """Per kind of task of ``robot`` (and all its tasks): labels and the bracket's gap.

    The gap is ``reference.upper − reference.lower`` of each task's reference row; empty
    without a stored reference.
    """
    if not rows.has_reference:
        return []
    mine = rows.select(robot=robot)
    oracle = {task_of(r): r for r in mine if is_reference(r)}
    passed = {task_of(r) for r in mine if r.get("success")}
    kinds = [(g.label, {task_of(r) for r in g.rows}) for g in task_groups(rows, robot)]
    kinds.append(("all tasks", set(oracle)))
    out = []
    for label, tasks in kinds:
        chosen = [oracle[t] for t in tasks if t in oracle]
        if not chosen:
            continue
        counts = tuple(sum(r.get("reference.status") == s for r in chosen) for s in BRACKET_LABELS)
        gaps = np.array(
            [number(r, "reference.upper") - number(r, "reference.lower") for r in chosen]
        )
        gaps = gaps[np.isfinite(gaps)]
        median, p90 = (
            (float(np.median(gaps)), float(np.percentile(gaps, 90)))
            if gaps.size
            else (math.nan, math.nan)
        )
        unpassed = sum(t not in passed for t in tasks if t in oracle)
        out.append(BracketRow(label, len(chosen), counts, median, p90, unpassed))
    return out


def success_flags(selected: list[dict[str, Any]]) -> dict[str, dict[tuple[object, ...], bool]]:
    """``controller → {task key → success}`` of the competitors among ``selected``."""
    flags: dict[str, dict[tuple[object, ...], bool]] = {}
    for row in selected:
        if not is_reference(row):
            flags.setdefault(row["controller"], {})[task_key(row)] = bool(row["success"])
    return flags


def _rate(flags: dict[tuple[object, ...], bool]) -> float:
    return sum(flags.values()) / len(flags) if flags else math.nan


@dataclass(frozen=True)
class Closest:
    """The beaten row closest to the pick, with the paired (McNemar) evidence.

    Attributes:
        name: The beaten row.
        pick_only: Tasks the pick alone succeeds on.
        other_only: Tasks the beaten row alone succeeds on.
        p_holm: Holm-adjusted exact McNemar p.
    """

    name: str
    pick_only: int
    other_only: int
    p_holm: float


@dataclass(frozen=True)
class GroupVerdict:
    """Whom to pick for a kind of task.

    Attributes:
        group: The group (label, reading, rows).
        tasks: Distinct tasks (× loop mode) in the group.
        outcome: See :data:`Outcome`.
        rates: ``controller → success rate`` [0, 1].
        ranking: The McNemar ranking (Holm), empty without two controllers.
        pick: The chosen row (``outcome == "pick"``), or the only one (``"single"``).
        not_separated: Rows sharing rank 1 with the pick (best rate first).
        beaten: How many rows the pick beats significantly.
        closest: The beaten row with the best rate, and the evidence, or None.
        tests: The group's paired McNemar tests (every pair), for the sizing advice
            (:func:`otmm_qp.studies.sizing.decision_advice`).
    """

    group: TaskGroup
    tasks: int
    outcome: Outcome
    rates: dict[str, float]
    ranking: tuple[Ranked, ...] = ()
    pick: str | None = None
    not_separated: tuple[str, ...] = ()
    beaten: int = 0
    closest: Closest | None = None
    tests: tuple[PairedRates, ...] = ()

    @property
    def leader(self) -> str | None:
        """The row a decision would favour: the pick, else the best rate (ties by name)."""
        if self.pick is not None:
            return self.pick
        if not self.rates:
            return None
        return max(self.rates, key=lambda name: (self.rates[name], name))


def _find_test(tests: list[PairedRates], a: str, b: str) -> PairedRates:
    return next(t for t in tests if {t.a, t.b} == {a, b})


def decide_group(group: TaskGroup) -> GroupVerdict:
    """The verdict of one group: success rates, McNemar ranking, pick and closest rival."""
    tasks = len({task_key(r) for r in group.rows})
    if not group.rows:
        return GroupVerdict(group, tasks, "no tasks", {})
    flags = success_flags(group.rows)
    rates = {name: _rate(f) for name, f in flags.items()}
    tests = paired_success(flags)
    ranking = tuple(paired_ranking(rates, tests, higher_is_better=True))
    if len(rates) == 1:
        return GroupVerdict(group, tasks, "single", rates, ranking, pick=next(iter(rates)))
    if all(rate == 0.0 for rate in rates.values()):
        return GroupVerdict(group, tasks, "none succeeds", rates, ranking, tests=tuple(tests))
    top = [r for r in ranking if r.rank == 1]
    if len(top) == len(ranking):
        return GroupVerdict(group, tasks, "not separated", rates, ranking, tests=tuple(tests))
    best = max(top, key=lambda r: (rates[r.name], r.name))
    others = tuple(r.name for r in top if r.name != best.name)
    beaten = [r for r in ranking if best.name in r.beaten_by]
    closest = None
    if beaten:
        runner = max(beaten, key=lambda r: (rates[r.name], r.name))
        test = _find_test(tests, best.name, runner.name)
        mine, theirs = (
            (test.a_only, test.b_only) if test.a == best.name else (test.b_only, test.a_only)
        )
        closest = Closest(runner.name, mine, theirs, test.p_holm)
    return GroupVerdict(
        group, tasks, "pick", rates, ranking, best.name, others, len(beaten), closest, tuple(tests)
    )


def median_intervals(rows: Rows, robot: str, metric: str) -> dict[str, Interval]:
    """``controller → median [interval]`` of ``metric`` on ``robot`` (the oracle included)."""
    out = {}
    for name in [*rows.controllers(), REFERENCE_NAME]:
        selected = rows.select(controller=name, robot=robot)
        if selected:
            values = np.array([number(r, metric) for r in selected])
            out[name] = bootstrap_interval(values, seed=0, resamples=RESAMPLES)
    return out


def paired_for(rows: Rows, robot: str, metric: str) -> list[PairedResult]:
    """Paired comparisons of every controller pair on ``robot``'s tasks (no oracle)."""
    values: dict[str, dict[tuple[object, ...], float]] = {}
    for row in rows.select(robot=robot):
        value = number(row, metric)
        if math.isfinite(value) and not is_reference(row) and row.get("status") != "error":
            values.setdefault(row["controller"], {})[task_key(row)] = value
    return paired_comparisons(values, seed=0, resamples=RESAMPLES)


@dataclass(frozen=True)
class AccuracyVerdict:
    """The most accurate rows of a robot by the paired Wilcoxon test of the headline accuracy.

    Attributes:
        metric: The headline accuracy column (``oracle_relative_error`` or ``max_error``).
        top: The rows not beaten in any paired test (Holm), in ranking order; empty when no
            row has a finite value.
        medians: ``controller → median [95 % interval]`` [m] of every row with a finite one.
        breaks: ``controller → (episodes breaking the arm's limits, episodes)`` of each row
            in ``top`` (:func:`~otmm_qp.studies.limit_keeping.limit_breaks`); ``top`` lists the
            rows that kept the limits on every task first.
    """

    metric: str
    top: tuple[str, ...]
    medians: dict[str, Interval]
    breaks: dict[str, tuple[int, int]] = field(default_factory=dict)

    @property
    def relative(self) -> bool:
        """Whether the metric is the oracle-relative error."""
        return self.metric == RELATIVE_ERROR


def accuracy_verdict(rows: Rows, robot: str) -> AccuracyVerdict:
    """The most accurate rows of ``robot`` (see :class:`AccuracyVerdict`)."""
    metric = rows.accuracy_metric()
    results = paired_for(rows, robot, metric)
    medians = {
        name: interval
        for name, interval in median_intervals(rows, robot, metric).items()
        if name != REFERENCE_NAME and math.isfinite(interval.value)
    }
    if not medians:
        return AccuracyVerdict(metric, (), {})
    ranking = paired_ranking({n: m.value for n, m in medians.items()}, results)
    own = rows.select(robot=robot)
    first = [r.name for r in ranking if r.rank == 1]
    breaks = {name: limit_breaks(own, name) for name in first}
    # rows that keep the arm's limits first (stable: the ranking order within each side)
    top = tuple(sorted(first, key=lambda name: breaks[name][0] > 0))
    return AccuracyVerdict(metric, top, medians, breaks)


def objectives(rows: Rows) -> tuple[str, ...]:
    """The Pareto objectives: the headline accuracy, then :data:`STUDY_OBJECTIVES`."""
    return (rows.accuracy_metric(), *STUDY_OBJECTIVES)


def study_fronts(rows: Rows) -> list[GroupFront]:
    """The Pareto front of every robot × generator group (see :mod:`otmm_qp.studies.fronts`)."""
    return group_fronts(rows.rows, objectives(rows), task_key, resamples=RESAMPLES)


def check_highlight(rows: Rows, highlight: str | None, option: str = "--highlight") -> None:
    """Refuse a ``--highlight`` (or ``option``) that names no controller of the study.

    Raises:
        ConfigError: ``highlight`` is not one of :meth:`Rows.controllers`.
    """
    if highlight is not None and highlight not in rows.controllers():
        raise ConfigError(
            option,
            f"no controller {highlight!r:.60} in the study; have: {', '.join(rows.controllers())}",
        )


@dataclass(frozen=True)
class SuccessLine:
    """One row of the success table.

    Attributes:
        controller: The row (``oracle`` last).
        episodes: Its episodes.
        errors: Episodes that never ran (``status == "error"``).
        rate: Success rate [0, 1] (None for the reference, which is not ranked).
        low: Wilson 95 % interval, low end (NaN for the reference).
        high: Its high end.
        medians: Median [bootstrap 95 % interval] of each requested metric.
    """

    controller: str
    episodes: int
    errors: int
    rate: float | None
    low: float
    high: float
    medians: tuple[Interval, ...]


def success_summary(rows: Rows, robot: str | None, metrics: Sequence[str]) -> list[SuccessLine]:
    """Success rate (Wilson) and medians (bootstrap) of every row on ``robot`` (None: all)."""
    out = []
    where = {"robot": robot} if robot else {}
    for name in [*rows.controllers(), REFERENCE_NAME]:
        selected = rows.select(controller=name, **where)
        if not selected:
            continue
        n = len(selected)
        errors = sum(1 for r in selected if r.get("status") == "error")
        rate, low, high = None, math.nan, math.nan
        if name != REFERENCE_NAME:
            wins = sum(1 for r in selected if r["success"])
            low, high = wilson_interval(wins, n)
            rate = wins / n
        medians = tuple(
            bootstrap_interval(
                np.array([number(r, metric) for r in selected]), seed=0, resamples=RESAMPLES
            )
            for metric in metrics
        )
        out.append(SuccessLine(name, n, errors, rate, low, high, medians))
    return out


def generator_rates(
    rows: Rows,
) -> tuple[list[tuple[str, str]], dict[str, list[tuple[float, float, float]]]]:
    """The (robot, generator) groups and ``controller → [(rate, Wilson low, high)]`` per group."""
    groups = list(dict.fromkeys((r["robot"], r["generator"]) for r in rows.rows))
    table: dict[str, list[tuple[float, float, float]]] = {}
    for name in rows.controllers():
        cells = []
        for robot, gen in groups:
            selected = rows.select(controller=name, robot=robot, generator=gen)
            wins = sum(1 for r in selected if r["success"])
            low, high = wilson_interval(wins, len(selected))
            rate = wins / len(selected) if selected else math.nan
            cells.append((rate, low, high))
        table[name] = cells
    return groups, table


def success_ranking(
    rows: Rows, robot: str, rates: dict[str, float]
) -> tuple[list[Ranked], list[PairedRates]]:
    """The McNemar ranking of ``robot``'s rows by success rate, and the tests (Holm)."""
    tests = paired_success(success_flags(rows.select(robot=robot)))
    return paired_ranking(rates, tests, higher_is_better=True), tests


def sigma_curves(
    rows: Rows, robot: str, metric: str
) -> tuple[np.ndarray, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """Binned medians of ``metric`` vs ``task.sigma_min_closest`` per controller on ``robot``."""
    selected = [r for r in rows.select(robot=robot) if number(r, "task.sigma_min_closest") > 0]
    if not selected:
        return np.zeros(0), {}
    sigma = np.array([number(r, "task.sigma_min_closest") for r in selected])
    edges = np.quantile(sigma, np.linspace(0.0, 1.0, SIGMA_BINS + 1))
    edges = np.unique(edges)
    if edges.size < 2:
        return np.zeros(0), {}
    curves = {}
    centres = np.zeros(0)
    for name in rows.controllers():
        own = [r for r in selected if r["controller"] == name]
        if not own:
            continue
        centres, medians, counts = binned_medians(
            np.array([number(r, "task.sigma_min_closest") for r in own]),
            np.array([number(r, metric) for r in own]),
            edges,
        )
        curves[name] = (medians, counts)
    return centres, curves
