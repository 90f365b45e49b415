r"""Is the accuracy–calm trade-off the task's? The offline optimum under the calm row's speeds.

For a stored study, per group of tasks (robot × generator, or a kind of task as
:func:`otmm_qp.studies.group_verdict.kind_rows` pools them), take two online rows: the
**calm** one (default: the front's lowest median peak joint speed,
:meth:`GroupFront.best_on` of ``max_joint_speed``) and the **accurate** one (default: the
lowest median oracle-relative max error). On every task *i* both ran, rebuild the task exactly
as the study did (:meth:`otmm_qp.studies.task.StudyTask.build`, same seed, weight and
duration) and solve the offline reference (:func:`otmm_qp.reference.solve_reference`, the
study's own tolerances and budget) with the speed cap

.. math::
    v_i = \max_{k \ge 1} \|\dot q^{calm}_{i,k}\|_\infty \quad [\mathrm{rad/s}],

the calm row's ``max_joint_speed`` on that task: every joint path it returns has
:math:`|q_{k+1} - q_k|/dt \le \min(\text{own limit}, v_i)`. Its largest position error
:math:`e^{*}_i(v_i)` [m] is compared, paired per task, with the accurate row's ``max_error``
:math:`e^{acc}_i` and the calm row's :math:`e^{calm}_i`: counts lower / tied / higher, median
difference :math:`e^{*}_i - e^{acc}_i`, Wilcoxon signed-rank p
(:func:`otmm_qp.studies.statistics.paired_test`), Holm over the groups (one family per
comparison). The tests clip every error at :func:`resolution` (the reference does not refine
errors below 1 % of the position tolerance, so smaller differences are ties).

Reading: if :math:`e^{*}_i(v_i) > e^{acc}_i` on most tasks (Holm-significant), then no joint
path as calm as the calm row on every task — online or offline — is as accurate as the
accurate row, so no strategy can be on top of both objectives: the trade-off is the task's.
The optimum is the reference's *position* optimum (:class:`~otmm_qp.reference.Bracket`:
``position_optimum``, orientation free), bracketed by its certified ``position_lower``;
"forced" needs that lower bound above the accurate row's error on most tasks as well. Without
it this is **evidence, not a proof**: the reference is a local method, so
:math:`e^{*}` is an upper bound on the true speed-bounded optimum (the calm row's own path is
feasible for the bound, so :math:`e^{*}_i > e^{calm}_i` flags the solver's locality and is
counted). The bound ignores one-step jumps — the optimum may jump arbitrarily — so it is a
lower bound for jump-limited strategies too, modulo that locality. A calm row whose peak
speed is 0 gets the cap :data:`SPEED_FLOOR` (the solver needs a positive one).

::

    otmm-qp study tradeoff DIR [--group-by generator|kind] [--calm ROW]
        [--accurate ROW] [--tasks N]
"""

from __future__ import annotations

import math
import sys
from collections.abc import Hashable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from otmm_qp.exceptions import ConfigError
from otmm_qp.output.markdown import Table, table_markdown
from otmm_qp.reference import LABELS, ReferenceResult, solve_reference
from otmm_qp.reference.solve import SETTLE
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.scenarios.generator import Task
from otmm_qp.studies.formatting import fmt as _fmt
from otmm_qp.studies.fronts import GroupFront, front_of, row_value
from otmm_qp.studies.oracle import REFERENCE_NAME, reference_settings
from otmm_qp.studies.rows import Rows, task_key
from otmm_qp.studies.schema import StudyConfig
from otmm_qp.studies.statistics import ALPHA, PairedResult, holm, paired_test
from otmm_qp.studies.task import StudyTask
from otmm_qp.studies.verdicts import RESAMPLES, objectives

#: How tasks are grouped: per robot × generator, or per kind of task pooled over robots.
GROUPINGS: tuple[str, ...] = ("generator", "kind")
#: Speed cap [rad/s] used when the calm row's peak joint speed on a task is 0.
SPEED_FLOOR = 1e-6
#: Name of the speed-bounded offline optimum in the paired tests.
BOUNDED = "bounded optimum"
#: What a group shows (see :meth:`GroupTradeoff.outcome`).
OUTCOMES: tuple[str, ...] = ("forced", "not forced", "undecided")

Row = dict[str, Any]


@dataclass(frozen=True)
class TaskTradeoff:
    """One task: the calm row's speed, the bounded optimum and both rows' errors.

    Attributes:
        key: The task (``task_key``: task id and loop mode).
        bound: Speed cap of the solve, the calm row's ``max_joint_speed`` [rad/s].
        bounded_error: Max position error of the speed-bounded position optimum [m] (the
            reference's ``bracket.position_optimum``: the smallest found within the cap).
        bounded_lower: Certified lower bound of it [m] (``bracket.position_lower``).
        bounded_speed: Largest ``|q_{k+1} − q_k|/dt`` of the reference path [rad/s]
            (≤ ``bound``).
        status: The solve's label (``achievable``, ``unachievable``, ``undecided`` or
            ``failed``).
        accurate_error: The accurate row's ``max_error`` [m].
        calm_error: The calm row's ``max_error`` [m].
        reference_error: The study's (unbounded-by-the-calm-row) reference ``max_error`` [m].
    """

    key: Hashable
    bound: float
    bounded_error: float
    bounded_lower: float
    bounded_speed: float
    status: str
    accurate_error: float
    calm_error: float
    reference_error: float


@dataclass(frozen=True)
class GroupTradeoff:
    """One group's paired evidence.

    Attributes:
        robot: Robot name (robots, comma-separated, for a pooled kind).
        group: Generator or kind of task.
        calm: The calm row.
        accurate: The accurate row.
        tasks: Per-task results, in task order.
        vs_accurate: Paired test, ``a`` = bounded optimum, ``b`` = accurate row (max error).
        vs_calm: Paired test, ``a`` = bounded optimum, ``b`` = calm row (max error).
        holm_accurate: Holm-adjusted p of ``vs_accurate`` over the groups.
        holm_calm: Holm-adjusted p of ``vs_calm`` over the groups.
    """

    robot: str
    group: str
    calm: str
    accurate: str
    tasks: tuple[TaskTradeoff, ...]
    vs_accurate: PairedResult
    vs_calm: PairedResult
    holm_accurate: float = math.nan
    holm_calm: float = math.nan

    def outcome(self, alpha: float = ALPHA) -> str:
        """What the group shows (one of :data:`OUTCOMES`).

        ``forced``: the bounded optimum's error is above the accurate row's on most tasks,
        Holm-significantly, *and* its certified lower bound is above the accurate row's
        error on most tasks (no path as calm as the calm row can be as accurate);
        ``not forced``: below on most tasks, Holm-significantly (a path as calm as the calm
        row *and* more accurate than the accurate row exists — offline, knowing the whole
        path; whether an online strategy can reach it is open); ``undecided`` otherwise.
        """
        test = self.vs_accurate
        if not self.holm_accurate < alpha:
            return OUTCOMES[2]
        certified = sum(t.bounded_lower > t.accurate_error for t in self.tasks)
        if test.favoured == self.accurate and test.higher > test.pairs / 2:
            return OUTCOMES[0] if certified > len(self.tasks) / 2 else OUTCOMES[2]
        if test.favoured == BOUNDED and test.lower > test.pairs / 2:
            return OUTCOMES[1]
        return OUTCOMES[2]


def _by_task(rows: Sequence[Row], controller: str) -> dict[Hashable, Row]:
    return {task_key(r): r for r in rows if r["controller"] == controller}


def rebuild_task(config: StudyConfig, row: Row) -> tuple[Robot, FloatArray | None, Task, float]:
    """The robot, task weight, task and duration [s] of a stored row, built as the study did.

    Raises:
        ConfigError: The row's robot or generator entry is not in the study, or the task
            cannot be generated again.
    """
    task = StudyTask.of_row(config, row)
    try:
        built = task.build(config)
    except Exception as error:  # noqa: BLE001 - a plugin's failure, said in one line
        reason = " ".join(str(error).split())[:200]
        raise ConfigError(
            str(row.get("task_id")), f"cannot rebuild the task: {type(error).__name__}: {reason}"
        ) from None
    return built.robot, built.weight, built.task, built.duration


def resolution(config: StudyConfig) -> float:
    """Smallest max error [m] the comparison resolves: ``SETTLE × position_tolerance``.

    The reference stops refining once every error is below ``SETTLE`` of its tolerance, so
    smaller errors are not minimised; the paired tests clip every error at this value (0
    without a position tolerance).
    """
    tolerance = reference_settings(config).position_tolerance
    return SETTLE * tolerance if tolerance is not None else 0.0


def bounded_optimum(
    config: StudyConfig,
    robot: Robot,
    weight: FloatArray | None,
    task: Task,
    duration: float,
    speed: float,
) -> ReferenceResult:
    """The study's offline reference of ``task`` with every joint speed ≤ ``speed`` [rad/s].

    The study's tolerances, σ_S and budget (:func:`reference_settings`) with
    ``speed_limit = max(speed, SPEED_FLOOR)`` (it replaces the study's own cap, if any).
    """
    settings = replace(reference_settings(config), speed_limit=max(speed, SPEED_FLOOR))
    result, _ = solve_reference(
        robot, task.trajectory, task.q0, config.dt, duration, settings, weight
    )
    return result


@dataclass
class _Solver:
    """Bounded optima cached by task id and bound (kinds overlap, so tasks repeat)."""

    config: StudyConfig
    cache: dict[tuple[object, float], ReferenceResult]

    def solve(self, row: Row, speed: float) -> ReferenceResult:
        key = (row.get("task_id"), speed)
        if key not in self.cache:
            robot, weight, task, duration = rebuild_task(self.config, row)
            self.cache[key] = bounded_optimum(self.config, robot, weight, task, duration, speed)
        return self.cache[key]


def _pick(front: GroupFront, named: str | None, k: int) -> str | None:
    return named if named is not None else front.best_on(k)


def group_tradeoff(
    solver: _Solver,
    front: GroupFront,
    rows: Sequence[Row],
    calm: str,
    accurate: str,
    tasks: int | None,
) -> GroupTradeoff:
    """Solve the bounded optimum on the group's tasks both rows ran (the first ``tasks``)."""
    calm_rows, accurate_rows = _by_task(rows, calm), _by_task(rows, accurate)
    keys = sorted(set(calm_rows) & set(accurate_rows), key=repr)
    keys = [
        k
        for k in keys
        if math.isfinite(row_value(calm_rows[k], "max_joint_speed"))
        and math.isfinite(row_value(accurate_rows[k], "max_error"))
        and math.isfinite(row_value(calm_rows[k], "max_error"))
    ][:tasks]
    out = []
    for k in keys:
        speed = row_value(calm_rows[k], "max_joint_speed")
        result = solver.solve(calm_rows[k], speed)
        out.append(
            TaskTradeoff(
                k,
                speed,
                float(result.bracket.position_optimum),
                float(result.bracket.position_lower),
                float(result.max_joint_speed),
                result.status,
                row_value(accurate_rows[k], "max_error"),
                row_value(calm_rows[k], "max_error"),
                row_value(calm_rows[k], "reference.max_error"),
            )
        )
    floor = resolution(solver.config)
    bounded = np.maximum([t.bounded_error for t in out], floor)

    def test(name: str, values: list[float]) -> PairedResult:
        other = np.maximum(np.array(values, dtype=float), floor)
        return paired_test(BOUNDED, name, bounded, other, 0, RESAMPLES)

    return GroupTradeoff(
        front.robot,
        front.group,
        calm,
        accurate,
        tuple(out),
        test(accurate, [t.accurate_error for t in out]),
        test(calm, [t.calm_error for t in out]),
    )


def _groups(rows: Rows, group_by: str) -> list[tuple[str, str, list[Row]]]:
    if group_by == "kind":
        from otmm_qp.studies.group_verdict import kind_rows

        robots = ", ".join(rows.robots())
        return [(robots, label, sel) for label, sel in kind_rows(rows).items() if sel]
    groups: dict[tuple[str, str], list[Row]] = {}
    for row in rows.rows:
        if row["controller"] != REFERENCE_NAME:
            groups.setdefault((row["robot"], row["generator"]), []).append(row)
    return [(robot, generator, sel) for (robot, generator), sel in groups.items()]


def check_row(rows: Rows, name: str | None, option: str) -> None:
    """Refuse a ``--calm``/``--accurate`` that names no online row of the study.

    Raises:
        ConfigError: One line naming the option, the value and the rows there are.
    """
    if name is not None and name not in rows.controllers():
        raise ConfigError(
            option,
            f"no online row {name!r:.60} in the study; have: {', '.join(rows.controllers())}",
        )


def study_tradeoff(
    config: StudyConfig,
    rows: Rows,
    group_by: str = GROUPINGS[0],
    calm: str | None = None,
    accurate: str | None = None,
    tasks: int | None = None,
) -> list[GroupTradeoff]:
    """:func:`group_tradeoff` of every group, with Holm over the groups.

    Groups whose calm and accurate rows are the same row are skipped (a row on top of both).

    Raises:
        ConfigError: ``group_by`` not in :data:`GROUPINGS`, an unknown row, the same row
            named calm and accurate, a study without reference rows, ``tasks`` < 1, or no
            task to compare in any group.
    """
    if group_by not in GROUPINGS:
        raise ConfigError("--group-by", f"{group_by!r:.40} is not one of {', '.join(GROUPINGS)}")
    check_row(rows, calm, "--calm")
    check_row(rows, accurate, "--accurate")
    if calm is not None and calm == accurate:
        raise ConfigError("--accurate", f"{accurate!r:.60} is the --calm row too; name another")
    if not rows.has_reference:
        raise ConfigError("study", "no offline reference rows stored (reference.enabled: true)")
    if tasks is not None and tasks < 1:
        raise ConfigError("--tasks", f"must be an integer >= 1, got {tasks}")
    solver = _Solver(config, {})
    out = []
    skipped = 0
    for robot, label, selected in _groups(rows, group_by):
        front = front_of(robot, label, selected, objectives(rows), task_key, RESAMPLES)
        calm_row, accurate_row = _pick(front, calm, 1), _pick(front, accurate, 0)
        if calm_row is None or accurate_row is None or calm_row == accurate_row:
            print(
                f"tradeoff: skipped {robot} / {label}: "
                + (f"{calm_row} is both the calm and the accurate row" if calm_row else "no row"),
                file=sys.stderr,
            )
            skipped += 1
            continue
        result = group_tradeoff(solver, front, selected, calm_row, accurate_row, tasks)
        if result.tasks:
            out.append(result)
    if not out:
        raise ConfigError(
            "study",
            f"nothing to compare: in {skipped} groups one row is both the calmest and the most "
            "accurate, in the others no task has finite values of both rows",
        )
    to_accurate = holm([_finite_p(g.vs_accurate) for g in out])
    to_calm = holm([_finite_p(g.vs_calm) for g in out])
    return [
        replace(g, holm_accurate=a, holm_calm=c)
        for g, a, c in zip(out, to_accurate, to_calm, strict=True)
    ]


def _finite_p(test: PairedResult) -> float:
    return test.p_value if math.isfinite(test.p_value) else 1.0


def _counts(test: PairedResult) -> str:
    return f"{test.lower}/{test.ties}/{test.higher}"


def render(groups: Sequence[GroupTradeoff], floor: float = 0.0) -> str:
    """Markdown: the per-group table and a plain sentence of what it shows.

    Args:
        groups: The groups of :func:`study_tradeoff`.
        floor: The :func:`resolution` the tests clipped errors at [m] (named in the text).
    """
    headers = ["robot", "group", "calm row", "accurate row", "tasks", "median speed cap [rad/s]"]
    headers += ["median error: bounded optimum / accurate / calm [m]"]
    headers += ["bounded − accurate: lower/tied/higher, median [m], Holm p"]
    headers += ["bounded − calm: lower/tied/higher, Holm p", "lower bound > accurate (tasks)"]
    headers += ["solves achievable/unachievable/undecided/failed", "trade-off"]
    cells: list[list[str]] = []
    for g in groups:
        status = [sum(t.status == s for t in g.tasks) for s in LABELS]
        certified = sum(t.bounded_lower > t.accurate_error for t in g.tasks)
        a, c = g.vs_accurate, g.vs_calm
        medians = " / ".join(
            _fmt(float(np.median([getattr(t, f) for t in g.tasks])))
            for f in ("bounded_error", "accurate_error", "calm_error")
        )
        cells.append([g.robot, g.group, g.calm, g.accurate, str(len(g.tasks))])
        cells[-1] += [_fmt(float(np.median([t.bound for t in g.tasks]))), medians]
        cells[-1] += [f"{_counts(a)}, {_fmt(a.median_difference.value)}, {_fmt(g.holm_accurate)}"]
        cells[-1] += [f"{_counts(c)}, {_fmt(g.holm_calm)}", str(certified)]
        cells[-1] += ["/".join(map(str, status)), g.outcome()]
    lines = table_markdown(Table(headers, cells))
    counts = {o: sum(g.outcome() == o for g in groups) for o in OUTCOMES}
    tasks = sum(len(g.tasks) for g in groups)
    above = sum(g.vs_accurate.higher for g in groups)
    below = sum(g.vs_accurate.lower for g in groups)
    local = sum(g.vs_calm.higher for g in groups)
    smallest = min(len(g.tasks) for g in groups)
    lines += [
        "",
        f"Over {len(groups)} groups and {tasks} tasks, the offline optimum under the calm "
        "row's per-task peak joint speed has a larger max error than the accurate row on "
        f"{above} tasks and a smaller one on {below}. Trade-off forced (above on most tasks, "
        f"Holm p < {ALPHA:g}, and the certified lower bound above the accurate row on most "
        f"tasks): {counts['forced']} groups — there no joint path as calm as the calm row on "
        "every task, online or offline, can be as accurate as the accurate row: the trade-off "
        "is the task's. Not forced (below on most tasks, Holm p < "
        f"{ALPHA:g}): {counts['not forced']} groups — there a path as calm as the calm row and "
        "more accurate than the accurate row exists: the task's kinematics and speeds do not "
        "force the trade-off (whether a causal, online strategy can reach that path is open: "
        "the optimum knows the whole path). "
        f"Undecided: {counts['undecided']} (the smallest group has n = {smallest} tasks: "
        f"its two-sided signed-rank p is at least 2·2⁻ⁿ = {2.0 ** (1 - smallest):.2g} before "
        f"Holm multiplies it by up to {len(groups)}). Evidence, not a "
        "proof: the offline solver is local, so its error is an upper bound on the bounded "
        "optimum (above the calm row's own error — a path within the same cap, position limits "
        "aside — on "
        f"{local} of {tasks} tasks); an 'above' that the lower bound does not certify reads "
        "'undecided', and 'not forced' is concrete (its path exists). The cap ignores "
        "one-step jumps (the optimum may jump "
        "arbitrarily), so the optimum is a lower bound for jump-limited strategies too, "
        f"modulo that locality. Errors below {floor:.2g} m (1 % of the position tolerance, "
        "which the solver does not refine) count as equal. Pose tasks: the error compared "
        "is the position error (as the oracle-relative error), and the optimum is the "
        "position-optimal one (orientation free), like the rows'.",
    ]
    return "\n".join(lines)
