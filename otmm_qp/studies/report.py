"""Study report: verdicts, Pareto figure, failure causes, then the detailed tables.

``write_study_report(DIR)`` reads ``DIR/study.json`` and the Parquet dataset and writes
``DIR/study_report.md``, ``DIR/study_report.html`` (the run report's style, figures embedded)
and ``DIR/figures/*.png``. Every number in them is computed here from the stored rows.

Per robot the report leads with the verdict in plain words — which controller to pick for
singular crossings, for beyond-reach motion and for limit-bound motion, each backed by the
exact McNemar test on the same tasks, and the most accurate one by the Wilcoxon test of the
oracle-relative error — and a Pareto figure, then the failure causes per controller and
generator, the worst episode of each controller (with its id for ``otmm-qp study show``) and
the detailed tables. Rows with ``controller == "oracle"`` are the task's offline reference:
shown as a row and a point, never ranked or tested; their ``reference.*`` columns (joined by
``task_id``) give every controller row its **oracle-relative error**
``max_error − reference.max_error`` [m].
"""

from __future__ import annotations

import base64
import io
import math
import re
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from otmm_qp.exceptions import ConfigError, OtmmError
from otmm_qp.metrics.table import STUDY_MEDIANS, STUDY_OBJECTIVES, STUDY_PAIRED, Metric
from otmm_qp.metrics.table import metric as metric_row
from otmm_qp.output.escape import escape
from otmm_qp.output.paths import atomic_write_bytes, atomic_write_text, ensure_inside, safe_name
from otmm_qp.studies.criteria import FAILURE_CAUSES, failure_causes, is_achievable
from otmm_qp.studies.drilldown import episode_id
from otmm_qp.studies.fronts import (
    GroupFront,
    counts_sentence,
    detail_table,
    group_fronts,
    summary_table,
)
from otmm_qp.studies.limit_keeping import limit_breaks, limits_clause
from otmm_qp.studies.oracle import REFERENCE_NAME, task_reference
from otmm_qp.studies.schema import StudyConfig
from otmm_qp.studies.sizing import decision_advice
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
    significant_digits,
    wilson_interval,
)
from otmm_qp.studies.storage import read_study_folder

#: Oracle-relative error column computed for every controller row [m].
RELATIVE_ERROR = metric_row("oracle_relative_error").name
#: Bootstrap resamples of every interval (printed digits follow their Monte-Carlo error).
RESAMPLES = 2000
#: Metrics summarised by median + bootstrap interval (rows of the metric table).
MEDIAN_METRICS: tuple[Metric, ...] = tuple(map(metric_row, STUDY_MEDIANS))
#: Metrics compared pairwise after the headline accuracy (rows of the metric table).
PAIRED_METRICS: tuple[Metric, ...] = tuple(map(metric_row, STUDY_PAIRED))
#: Bins of σ_min at closest approach (log-spaced edges).
SIGMA_BINS = 6


@dataclass
class Rows:
    """Episode rows as Python dicts, with success and failure causes recomputed.

    ``controllers()`` lists the competitors only; the ``oracle`` rows are in ``rows`` too
    (select them with ``controller=REFERENCE_NAME``).
    """

    rows: list[dict[str, Any]]

    def controllers(self) -> list[str]:
        """Competing controllers in first-seen order (the reference excluded)."""
        return list(dict.fromkeys(r["controller"] for r in self.rows if not _is_oracle(r)))

    def robots(self) -> list[str]:
        """Robots in first-seen order."""
        return list(dict.fromkeys(r["robot"] for r in self.rows))

    def select(self, **equal: Any) -> list[dict[str, Any]]:
        """Rows whose columns equal the given values."""
        return [r for r in self.rows if all(r.get(k) == v for k, v in equal.items())]

    @property
    def has_reference(self) -> bool:
        """Whether any task has an offline reference."""
        return any(_is_oracle(r) or _known(r.get("reference.achievable")) for r in self.rows)

    def accuracy_metric(self) -> str:
        """The headline accuracy column: oracle-relative error, or max error without reference."""
        return RELATIVE_ERROR if self.has_reference else "max_error"


def _is_oracle(row: dict[str, Any]) -> bool:
    return row.get("controller") == REFERENCE_NAME


def _known(value: Any) -> bool:
    return value is not None and not (isinstance(value, float) and math.isnan(value))


def _value(row: dict[str, Any], name: str) -> float:
    value = row.get(name)
    if value is None or isinstance(value, str):
        return math.nan
    return float(value)


def task_key(row: dict[str, Any]) -> tuple[object, ...]:
    """The task an episode ran on (``task_id`` when stored) and its loop mode."""
    task = row.get("task_id") or (
        row["robot"],
        row["generator"],
        row.get("generator_params"),
        row["task_index"],
    )
    return (task, row["loop_mode"])


def _task(row: dict[str, Any]) -> object:
    return task_key(row)[0]


def _fmt(value: float, digits: int = 3) -> str:
    if not math.isfinite(value):
        return "–"
    return f"{value:.{digits}g}"


def _interval(value: float | Interval, low: float = math.nan, high: float = math.nan) -> str:
    """``value [low, high]``; endpoints with only the digits their Monte-Carlo error fixes."""
    if isinstance(value, Interval):
        digits = [significant_digits(e, value.mc_error) for e in (value.low, value.high)]
        return f"{_fmt(value.value)} [{_fmt(value.low, digits[0])}, {_fmt(value.high, digits[1])}]"
    return f"{_fmt(value)} [{_fmt(low)}, {_fmt(high)}]"


def join_reference(rows: list[dict[str, Any]]) -> None:
    """Copy each ``oracle`` row's ``reference.*`` columns onto the rows of its task, in place.

    Columns already on a row are kept; ``reference.max_error`` falls back to the oracle row's
    ``max_error`` and ``reference.final_error`` is its ``final_error``. Then every row gets
    :data:`RELATIVE_ERROR` = ``max_error − reference.max_error`` (NaN without a reference).
    """
    references: dict[object, dict[str, Any]] = {}
    for row in rows:
        if not _is_oracle(row):
            continue
        references[_task(row)] = task_reference(row)
    for row in rows:
        for name, value in references.get(_task(row), {}).items():
            if not _known(row.get(name)):
                row[name] = value
        row[RELATIVE_ERROR] = _value(row, "max_error") - _value(row, "reference.max_error")


def load_rows(out: Path) -> tuple[StudyConfig, Rows]:
    """The study config and its rows: references joined, success and causes recomputed.

    Only the rows of this study and plan are read (``study.json``).

    What the reader left out (other studies' parts, symlinks, duplicates...) is printed on
    stderr, one line per reason.

    Raises:
        OtmmError: No study marker, an invalid one, or no episodes in ``out``.
    """
    config, data = read_study_folder(out)
    for line in data.ignored:
        print(f"otmm-qp: report ignored {line}", file=sys.stderr)
    if data.table is None or data.table.num_rows == 0:
        raise OtmmError(f"{out}: the study has no stored episodes yet")
    rows = data.table.to_pylist()
    join_reference(rows)
    for row in rows:
        if not row.get("episode_id"):
            row["episode_id"] = episode_id(str(row.get("episode_key", "")))
        causes = () if _is_oracle(row) else failure_causes(row, config.success)
        row["failure_causes"] = causes
        row["success"] = not causes
    return config, Rows(rows)


def _median_metrics(rows: Rows) -> tuple[Metric, ...]:
    if rows.has_reference:
        return (metric_row(RELATIVE_ERROR), *MEDIAN_METRICS)
    return MEDIAN_METRICS


def success_table(
    rows: Rows, robot: str | None
) -> tuple[list[str], dict[str, tuple[float, float, float]]]:
    """Markdown lines of success rates and medians, and ``controller → (rate, low, high)``.

    The reference (``oracle``) is the last row, without a success rate.
    """
    metrics = _median_metrics(rows)
    header = (
        "| controller | episodes | errors | success [95 % CI] | "
        + " | ".join(f"median {m.heading} (95 % CI)" for m in metrics)
        + " |"
    )
    lines = [header, "|" + "---|" * (4 + len(metrics))]
    rates: dict[str, tuple[float, float, float]] = {}
    where = {"robot": robot} if robot else {}
    for name in [*rows.controllers(), REFERENCE_NAME]:
        selected = rows.select(controller=name, **where)
        if not selected:
            continue
        n = len(selected)
        errors = sum(1 for r in selected if r.get("status") == "error")
        if name == REFERENCE_NAME:
            rate = "reference (not ranked)"
        else:
            wins = sum(1 for r in selected if r["success"])
            low, high = wilson_interval(wins, n)
            rates[name] = (wins / n, low, high)
            rate = f"{100 * wins / n:.1f} % [{100 * low:.1f}, {100 * high:.1f}]"
        cells = [name, str(n), str(errors), rate]
        for row in metrics:
            values = np.array([_value(r, row.name) for r in selected])
            cells.append(_interval(bootstrap_interval(values, seed=0, resamples=RESAMPLES)))
        lines.append("| " + " | ".join(cells) + " |")
    return lines, rates


def generator_table(rows: Rows) -> list[str]:
    """Markdown table: success rate [CI] per controller (rows) and robot/generator (columns)."""
    groups = list(dict.fromkeys((r["robot"], r["generator"]) for r in rows.rows))
    lines = [
        "| controller | " + " | ".join(f"{robot} {gen}" for robot, gen in groups) + " |",
        "|---|" + "---|" * len(groups),
    ]
    for name in rows.controllers():
        cells = []
        for robot, gen in groups:
            selected = rows.select(controller=name, robot=robot, generator=gen)
            wins = sum(1 for r in selected if r["success"])
            low, high = wilson_interval(wins, len(selected))
            rate = 100 * wins / len(selected) if selected else math.nan
            cells.append(f"{rate:.0f} % [{100 * low:.0f}, {100 * high:.0f}]")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return lines


def median_intervals(rows: Rows, robot: str, metric: str) -> dict[str, Interval]:
    """``controller → median [interval]`` of ``metric`` on ``robot`` (the oracle included)."""
    out = {}
    for name in [*rows.controllers(), REFERENCE_NAME]:
        selected = rows.select(controller=name, robot=robot)
        if selected:
            values = np.array([_value(r, metric) for r in selected])
            out[name] = bootstrap_interval(values, seed=0, resamples=RESAMPLES)
    return out


def paired_for(rows: Rows, robot: str, metric: str) -> list[PairedResult]:
    """Paired comparisons of every controller pair on ``robot``'s tasks (no oracle)."""
    values: dict[str, dict[tuple[object, ...], float]] = {}
    for row in rows.select(robot=robot):
        value = _value(row, metric)
        if math.isfinite(value) and not _is_oracle(row) and row.get("status") != "error":
            values.setdefault(row["controller"], {})[task_key(row)] = value
    return paired_comparisons(values, seed=0, resamples=RESAMPLES)


def success_flags(selected: list[dict[str, Any]]) -> dict[str, dict[tuple[object, ...], bool]]:
    """``controller → {task key → success}`` of the competitors among ``selected``."""
    flags: dict[str, dict[tuple[object, ...], bool]] = {}
    for row in selected:
        if not _is_oracle(row):
            flags.setdefault(row["controller"], {})[task_key(row)] = bool(row["success"])
    return flags


@dataclass(frozen=True)
class TaskGroup:
    """A kind of motion a verdict is given for: a label, how its tasks are chosen, its rows."""

    label: str
    reading: str
    rows: list[dict[str, Any]]


def task_groups(rows: Rows, robot: str) -> list[TaskGroup]:
    """Singular crossings, beyond-reach and limit-bound tasks of ``robot``'s competitor rows.

    With a reference: ``reference.near_singular`` and achievable, ``reference.achievable``
    false, ``reference.touches_position_limit``; without one, by generator (``near_singular``
    and ``joint_path``; ``beyond_reach``; limit-bound tasks cannot be told).
    """
    own = [r for r in rows.select(robot=robot) if not _is_oracle(r)]
    if rows.has_reference:

        def flag(row: dict[str, Any], name: str) -> bool:
            value = row.get(name)
            return _known(value) and bool(value)

        return [
            TaskGroup(
                "singular crossings",
                "tasks whose reference passes near a singularity (σ_min < σ_S) and is achievable",
                [
                    r
                    for r in own
                    if flag(r, "reference.near_singular") and flag(r, "reference.achievable")
                ],
            ),
            TaskGroup(
                "beyond-reach motion",
                "tasks the reference finds unachievable (judged by the graceful criteria)",
                [r for r in own if not is_achievable(r)],
            ),
            TaskGroup(
                "limit-bound motion",
                "tasks whose reference touches a position limit",
                [r for r in own if flag(r, "reference.touches_position_limit")],
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


def _rate(flags: dict[tuple[object, ...], bool]) -> tuple[float, int]:
    return (sum(flags.values()) / len(flags) if flags else math.nan), len(flags)


def _pct(value: float) -> str:
    return f"{100 * value:.0f} %" if math.isfinite(value) else "–"


def _p(value: float) -> str:
    return f"{value:.2g}" if math.isfinite(value) else "–"


def group_verdict(group: TaskGroup) -> str:
    """One plain-words verdict line: whom to pick for the group, with the paired evidence."""
    tasks = len({task_key(r) for r in group.rows})
    head = f"- **{group.label.capitalize()}** ({tasks} tasks: {group.reading}): "
    if not group.rows:
        return head + "no such tasks in this study."
    flags = success_flags(group.rows)
    rates = {name: _rate(f)[0] for name, f in flags.items()}
    tests = paired_success(flags)
    ranking = paired_ranking(rates, tests, higher_is_better=True)
    if len(rates) == 1:
        name, rate = next(iter(rates.items()))
        return head + f"only {name} ran (success {_pct(rate)})."
    if all(rate == 0.0 for rate in rates.values()):
        return head + "no controller succeeds on any of them."
    top = [r for r in ranking if r.rank == 1]
    best = max(top, key=lambda r: (rates[r.name], r.name))
    if len(top) == len(ranking):
        return (
            head
            + "no paired test separates the controllers, so none is to be preferred here ("
            + ", ".join(
                f"{r.name} {_pct(rates[r.name])}"
                for r in sorted(ranking, key=lambda r: (-rates[r.name], r.name))
            )
            + "); "
            + decision_advice(best.name, tests)
            + "."
        )
    text = head + f"pick **{best.name}** (success {_pct(rates[best.name])})"
    others = [r for r in top if r.name != best.name]
    if others:
        text += "; not separated from it by the paired test: " + ", ".join(
            f"{r.name} ({_pct(rates[r.name])})" for r in others
        )
        text += "; " + decision_advice(best.name, tests)
    beaten = [r for r in ranking if best.name in r.beaten_by]
    if beaten:
        runner = max(beaten, key=lambda r: (rates[r.name], r.name))
        test = _find_test(tests, best.name, runner.name)
        mine, theirs = (
            (test.a_only, test.b_only) if test.a == best.name else (test.b_only, test.a_only)
        )
        text += (
            f"; it beats {len(beaten)} of the others, the closest {runner.name} "
            f"({_pct(rates[runner.name])}: {best.name} alone succeeds on {mine} tasks, "
            f"{runner.name} alone on {theirs}, McNemar Holm p = {_p(test.p_holm)})"
        )
    return text + "."


def _find_test(tests: list[PairedRates], a: str, b: str) -> PairedRates:
    return next(t for t in tests if {t.a, t.b} == {a, b})


def accuracy_verdict(rows: Rows, robot: str) -> str:
    """The most accurate controller by the paired Wilcoxon test of the headline accuracy."""
    metric = rows.accuracy_metric()
    label = "oracle-relative max error" if metric == RELATIVE_ERROR else "max error"
    results = paired_for(rows, robot, metric)
    medians = {
        name: interval
        for name, interval in median_intervals(rows, robot, metric).items()
        if name != REFERENCE_NAME and math.isfinite(interval.value)
    }
    if not medians:
        return f"- **Accuracy ({label})**: no finite values."
    ranking = paired_ranking({n: m.value for n, m in medians.items()}, results)
    own = rows.select(robot=robot)
    # rows that keep the arm's limits first; the others say how often they break them
    top = sorted(
        (r for r in ranking if r.rank == 1), key=lambda r: limit_breaks(own, r.name)[0] > 0
    )
    shown = ", ".join(
        f"{r.name} {_interval(medians[r.name])} m{limits_clause(own, r.name)}" for r in top[:4]
    )
    more = f" (+{len(top) - 4} more)" if len(top) > 4 else ""
    return (
        f"- **Accuracy ({label}, median [95 % CI])**: lowest, not beaten in any paired "
        f"Wilcoxon test (Holm p < {ALPHA:g}): {shown}{more}."
    )


def _verdicts(rows: Rows, robot: str) -> list[str]:
    """The plain-words verdict lines of ``robot``."""
    lines = [group_verdict(group) for group in task_groups(rows, robot)]
    lines.append(accuracy_verdict(rows, robot))
    return lines


def _ranking_line(ranking: list[Ranked], what: str, test: str) -> str:
    return (
        f"Ranking by {what} (rank = 1 + the number of controllers that beat it in the paired "
        f"{test}, Holm p < {ALPHA:g}; = marks a shared rank, i.e. as many controllers beat "
        "each; it does not say the two are indistinguishable): "
        + ", ".join(f"{r.rank}{'=' if r.tied else ''} {r.name}" for r in ranking)
    )


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


def render_markdown(
    config: StudyConfig, rows: Rows, figures: Sequence[str], highlight: str | None = None
) -> str:
    """The Markdown report: the decision per kind of task first, then the method and details.

    Per robot after the method: fronts → figure → causes → details.

    Args:
        config: The study record.
        rows: Its rows (:func:`load_rows`).
        figures: Relative paths of the figures written.
        highlight: A controller marked as *ours* on every group's Pareto front, or None.
    """
    check_highlight(rows, highlight)
    fronts = study_fronts(rows)
    overview = _overview(config, rows)
    cut = overview.index(_criteria_text(config))
    out = overview[:cut]  # title, description, counts; then the answer, then the method
    out += ["## Decision per kind of task", ""]
    for robot in rows.robots():
        out += [f"### Verdict on {robot}", "", *_verdicts(rows, robot), ""]
    out += ["## Method", "", *overview[cut:]]
    out += _fronts_overview(fronts, highlight)
    for robot in rows.robots():
        own = [f for f in fronts if f.robot == robot]
        out += _robot_section(rows, robot, figures, own, highlight)
        out += _front_details(own, highlight)
    lines, _ = success_table(rows, None)
    out += ["## All robots", "", *lines, ""]
    out += [
        "## Success rate by robot and generator (95 % Wilson CI)",
        "",
        *generator_table(rows),
        "",
    ]
    rest = [f for f in figures if f not in {_pareto_path(r) for r in rows.robots()}]
    if rest:
        out += ["## Figures", ""] + [f"![{f}]({f})" for f in rest] + [""]
    return "\n".join(out)


def _pareto_path(robot: str) -> str:
    return f"figures/{safe_name(f'pareto-{robot}.png')}"


def _criteria_text(config: StudyConfig) -> str:
    c = config.success
    speed = (
        f"peak joint speed ‖q̇‖∞ ≤ {c.max_joint_speed:g} rad/s"
        if c.max_joint_speed is not None
        else f"every joint within {c.joint_speed_factor:g} × its own velocity limit"
    )
    error = f"max position error ≤ {c.max_position_error:g} m" if c.max_position_error else ""
    if c.max_orientation_error:
        error += f", max orientation error ≤ {c.max_orientation_error:g} rad"
    g = c.graceful
    return (
        f"Success on achievable tasks: completed, {error}, {speed}"
        + (", no position-limit violation" if c.no_limit_violation else "")
        + (", no blow-up" if c.no_blow_up else "")
        + ". On tasks the reference finds unachievable (graceful): the same speed, limit and "
        f"blow-up bounds, max error ≤ {g.error_factor:g} × the reference's"
        + (
            ", final error back within the tolerance (or that factor of the reference's)"
            if g.return_to_path
            else ""
        )
        + f", no chatter (one-step joint-speed change ≤ {g.max_jump_factor:g} × the joint's "
        "velocity limit)."
    )


def _overview(config: StudyConfig, rows: Rows) -> list[str]:
    """Report title, description, what was run, the criteria and the statistics used."""
    competitors = [r for r in rows.rows if not _is_oracle(r)]
    errors = sum(1 for r in competitors if r.get("status") == "error")
    tasks = len({_task(r) for r in rows.rows})
    reference = (
        f"Each task's offline-optimal reference ({REFERENCE_NAME} rows) is shown as a row and "
        "a point, "
        "never ranked; accuracy is the oracle-relative error max_error − reference.max_error."
        if rows.has_reference
        else "No offline reference is stored: tasks are judged by the tolerances alone and "
        "accuracy is the max error."
    )
    return [
        f"# Study {config.name}",
        "",
        config.description,
        "",
        f"{len(competitors)} controller episodes ({errors} errors)"
        + (
            f" + {len(rows.rows) - len(competitors)} offline references = {len(rows.rows)} "
            "episodes stored (the count `otmm-qp study` prints)"
            if len(rows.rows) > len(competitors)
            else ""
        )
        + f" on {tasks} tasks; robots: "
        f"{', '.join(rows.robots())}; controllers: {len(rows.controllers())}; "
        f"loop modes: {', '.join(config.loop_modes)}; dt = {config.dt:g} s.",
        "",
        _criteria_text(config),
        "",
        reference,
        "",
        "Statistics: Wilson 95 % intervals for rates; medians with percentile-bootstrap 95 % "
        f"intervals ({RESAMPLES} resamples, seed 0; endpoints printed to the digits their "
        "Monte-Carlo error fixes); success compared on the same tasks by the exact McNemar "
        "test, metrics by the Wilcoxon signed-rank test with the side it favours; Holm across "
        "the pairs of each table.",
        "",
    ]


def _fronts_overview(fronts: Sequence[GroupFront], highlight: str | None) -> list[str]:
    """How the Pareto fronts are built, and the counts over every group."""
    names = ", ".join(metric_row(m).heading for m in fronts[0].objectives) if fronts else ""
    return [
        "Pareto fronts, per robot × generator, over the online rows' medians of "
        f"{names} (all minimised). Each row is compared on each objective with the other row "
        "of lowest median by the paired Wilcoxon test on the same tasks; it *meets the "
        f"criterion* when no comparison is worse and one is better (Holm p < {ALPHA:g}; Holm "
        "over all its pairs, or over its tests against the best others only — both readings "
        "shown).",
        "",
        counts_sentence(fronts, _ours(highlight)),
        "",
    ]


def _ours(highlight: str | None) -> Callable[[str], bool]:
    def ours(name: str) -> bool:
        return name == highlight

    return ours


def _front_details(fronts: Sequence[GroupFront], highlight: str | None) -> list[str]:
    """Per group of one robot: every row's medians, place on the front and paired tests."""
    out: list[str] = []
    for front in fronts:
        out += [
            f"### {front.robot} / {front.group}: medians, front and paired tests",
            "",
            *detail_table(front, _ours(highlight)),
            "",
        ]
    return out


def _robot_section(
    rows: Rows,
    robot: str,
    figures: Sequence[str],
    fronts: Sequence[GroupFront] = (),
    highlight: str | None = None,
) -> list[str]:
    """One robot: Pareto fronts, figure, failure causes, worst episodes, tables.

    Its verdict lines open the report (``## Decision per kind of task``).
    """
    out = [f"## {robot}", ""]
    if fronts:
        out += [f"### Pareto fronts on {robot}", "", *summary_table(fronts, _ours(highlight)), ""]
    pareto = _pareto_path(robot)
    if pareto in figures:
        out += [f"![Pareto: {robot}]({pareto})", ""]
    out += _cause_table(rows, robot)
    out += _worst_table(rows, robot)
    out += ["### Success rates and medians", ""]
    lines, rates = success_table(rows, robot)
    out += lines + [""]
    flags = success_flags(rows.select(robot=robot))
    tests = paired_success(flags)
    ranking = paired_ranking({n: v[0] for n, v in rates.items()}, tests, higher_is_better=True)
    out += [_ranking_line(ranking, "success rate", "McNemar test"), ""]
    out += _mcnemar_table(tests, robot)
    for paired in (rows.accuracy_metric(), *(m.name for m in PAIRED_METRICS)):
        out += _paired_table(rows, robot, paired)
    for metric in ("max_error", "max_joint_speed"):
        out += _sigma_table(rows, robot, metric)
    return out


def _cause_table(rows: Rows, robot: str) -> list[str]:
    """Episodes failing each criterion, per controller × generator (one can fail several)."""
    out = [
        f"### Failure causes on {robot}",
        "",
        "Episodes failing each criterion (an episode can fail several): *error* = tolerance "
        "(achievable tasks) or graceful error bound (unachievable), *speed* = speed bound, "
        "*position_limit* = a joint left its limits, *blow_up*, *stuck* = stopped early, "
        "*chatter* (unachievable tasks), *run_error* = never ran.",
        "",
        "| controller | generator | episodes | success | " + " | ".join(FAILURE_CAUSES) + " |",
        "|---|---|---|---|" + "---|" * len(FAILURE_CAUSES),
    ]
    generators = list(dict.fromkeys(r["generator"] for r in rows.select(robot=robot)))
    for name in rows.controllers():
        for gen in generators:
            selected = rows.select(controller=name, robot=robot, generator=gen)
            if not selected:
                continue
            wins = sum(1 for r in selected if r["success"])
            counts = [sum(1 for r in selected if c in r["failure_causes"]) for c in FAILURE_CAUSES]
            out.append(
                f"| {name} | {gen} | {len(selected)} | {_pct(wins / len(selected))} | "
                + " | ".join(str(c) for c in counts)
                + " |"
            )
    out.append("")
    return out


def _worst_table(rows: Rows, robot: str) -> list[str]:
    """Each controller's worst episode by the headline accuracy, with its drill-down id."""
    metric = rows.accuracy_metric()
    out = [
        f"### Worst episode of each controller on {robot} (by {metric})",
        "",
        "`otmm-qp study show DIR --episode ID` prints an episode and writes a config that "
        "re-runs it.",
        "",
        f"| controller | id | task | {metric} [m] | peak joint speed [rad/s] | failure causes |",
        "|---|---|---|---|---|---|",
    ]
    for name in rows.controllers():
        ran = [
            r for r in rows.select(controller=name, robot=robot) if math.isfinite(_value(r, metric))
        ]
        if not ran:
            continue
        worst = max(ran, key=lambda r: (_value(r, metric), str(r.get("episode_key"))))
        task = worst.get("task_id") or f"{worst['generator']}/{worst['task_index']}"
        out.append(
            f"| {name} | `{worst['episode_id']}` | {task} | {_fmt(_value(worst, metric))} | "
            f"{_fmt(_value(worst, 'max_joint_speed'))} | "
            f"{', '.join(worst['failure_causes']) or 'none'} |"
        )
    out.append("")
    return out


def _mcnemar_table(tests: list[PairedRates], robot: str) -> list[str]:
    out = [
        f"### Paired success on {robot} (exact McNemar on the same tasks)",
        "",
        "| A | B | tasks | A only | B only | both | p | Holm p | favours |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for t in tests:
        side = t.favoured or "neither"
        mark = " *" if t.significant else ""
        out.append(
            f"| {t.a} | {t.b} | {t.pairs} | {t.a_only} | {t.b_only} | {t.both} | "
            f"{_p(t.p_value)} | {_p(t.p_holm)}{mark} | {side} |"
        )
    out.append("")
    return out


def _paired_table(rows: Rows, robot: str, metric: str) -> list[str]:
    """Markdown table of the paired comparisons of ``metric`` on ``robot`` (Holm p < 0.05: *)."""
    out = [
        f"### Paired comparisons on {robot}: {metric} (lower wins)",
        "",
        "*favours*: the side the signed-rank sums favour (W⁻ > W⁺: A); ⚠ where the strict "
        "counts or the median difference point the other way.",
        "",
        "| A | B | tasks | A lower | ties | A higher | median A−B [95 % CI] | "
        "Hodges–Lehmann | Wilcoxon p | Holm p | favours |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in paired_for(rows, robot, metric):
        side = r.favoured or "neither"
        flags = (" *" if r.significant else "") + ("" if r.consistent else " ⚠")
        out.append(
            f"| {r.a} | {r.b} | {r.pairs} | {r.lower} | {r.ties} | {r.higher} | "
            f"{_interval(r.median_difference)} | {_fmt(r.hodges_lehmann)} | {_p(r.p_value)} | "
            f"{_p(r.p_holm)} | {side}{flags} |"
        )
    out.append("")
    return out


def sigma_curves(
    rows: Rows, robot: str, metric: str
) -> tuple[np.ndarray, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """Binned medians of ``metric`` vs ``task.sigma_min_closest`` per controller on ``robot``."""
    selected = [r for r in rows.select(robot=robot) if _value(r, "task.sigma_min_closest") > 0]
    if not selected:
        return np.zeros(0), {}
    sigma = np.array([_value(r, "task.sigma_min_closest") for r in selected])
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
            np.array([_value(r, "task.sigma_min_closest") for r in own]),
            np.array([_value(r, metric) for r in own]),
            edges,
        )
        curves[name] = (medians, counts)
    return centres, curves


def _sigma_table(rows: Rows, robot: str, metric: str) -> list[str]:
    """Markdown table of ``metric``'s binned medians vs σ_min at closest approach (or none)."""
    centres, curves = sigma_curves(rows, robot, metric)
    if not curves:
        return []
    out = [
        f"### {robot}: median {metric} vs σ_min at closest approach",
        "",
        "| controller | " + " | ".join(f"σ≈{_fmt(c, 2)}" for c in centres) + " |",
        "|---|" + "---|" * len(centres),
    ]
    for name, (medians, counts) in curves.items():
        cells = [f"{_fmt(m)} (n={c})" for m, c in zip(medians, counts, strict=True)]
        out.append(f"| {name} | " + " | ".join(cells) + " |")
    out.append("")
    return out


def _save(figure: Any, out: Path, name: str) -> str:
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=90)
    plt.close(figure)
    relative = f"figures/{safe_name(name)}"
    atomic_write_bytes(ensure_inside(out, out / relative), buffer.getvalue())
    return relative


def write_figures(out: Path, rows: Rows) -> list[str]:
    """ECDFs per metric, σ_min curves and a Pareto plot per robot; relative paths."""
    import matplotlib

    matplotlib.use("Agg")

    (out / "figures").mkdir(exist_ok=True)
    written = []
    for robot in rows.robots():
        written.append(_ecdf_figure(out, rows, robot))
        sigma = _sigma_figure(out, rows, robot)
        if sigma is not None:
            written.append(sigma)
        written.append(_pareto_figure(out, rows, robot))
    return written


def _positive_sorted(rows: Rows, robot: str, controller: str, metric: str) -> np.ndarray:
    """Finite values > 0 of ``metric`` of one controller on ``robot``, sorted."""
    return np.sort(
        [
            v
            for v in (_value(r, metric) for r in rows.select(robot=robot, controller=controller))
            if math.isfinite(v) and v > 0
        ]
    )


def _ecdf_figure(out: Path, rows: Rows, robot: str) -> str:
    """Write ``robot``'s ECDFs of the median metrics, one panel each; its relative path."""
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, len(MEDIAN_METRICS), figsize=(4 * len(MEDIAN_METRICS), 3.4))
    for ax, row in zip(axes, MEDIAN_METRICS, strict=True):
        for name in rows.controllers():
            values = _positive_sorted(rows, robot, name, row.name)
            if values.size:
                ax.step(
                    values,
                    np.arange(1, values.size + 1) / values.size,
                    where="post",
                    label=name,
                )
        ax.set_xscale("log")
        ax.set_xlabel(row.heading)
        ax.set_ylabel("fraction of episodes")
    axes[0].legend(fontsize=6)
    figure.suptitle(f"{robot}: ECDFs")
    figure.subplots_adjust(left=0.08, right=0.98, bottom=0.16, top=0.88, wspace=0.3)
    return _save(figure, out, f"ecdf-{robot}.png")


def _sigma_figure(out: Path, rows: Rows, robot: str) -> str | None:
    """Write ``robot``'s medians vs σ_min at closest approach; its relative path, or None."""
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, 2, figsize=(9, 3.4))
    drawn = False
    for ax, metric in zip(axes, ("max_error", "max_joint_speed"), strict=True):
        centres, curves = sigma_curves(rows, robot, metric)
        for name, (medians, _) in curves.items():
            ax.plot(centres, medians, marker="o", label=name)
            drawn = True
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("σ_min at closest approach")
        ax.set_ylabel(f"median {metric}")
    if not drawn:
        plt.close(figure)
        return None
    axes[0].legend(fontsize=6)
    figure.suptitle(f"{robot}: metrics vs σ_min at closest approach")
    figure.subplots_adjust(left=0.08, right=0.98, bottom=0.16, top=0.88, wspace=0.3)
    return _save(figure, out, f"sigma-{robot}.png")


def _pareto_figure(out: Path, rows: Rows, robot: str) -> str:
    """Write ``robot``'s median accuracy vs median peak joint speed, with CIs; its path.

    Accuracy is the oracle-relative max error (the reference is the point at 0; symmetric-log
    axis, since a controller can beat a heuristic reference on some tasks and the relative
    error can be negative), or the max error (log axis) when no reference is stored.
    """
    import matplotlib.pyplot as plt

    metric = rows.accuracy_metric()
    errors = median_intervals(rows, robot, metric)
    speeds = median_intervals(rows, robot, "max_joint_speed")
    figure, ax = plt.subplots(figsize=(6.4, 4.6))
    for name in errors:
        e, s = errors[name], speeds[name]
        if not (math.isfinite(e.value) and math.isfinite(s.value)):
            continue
        if name == REFERENCE_NAME:
            ax.plot(
                s.value,
                0.0,
                marker="*",
                markersize=14,
                color="k",
                linestyle="none",
                label="oracle (reference)",
            )
            continue
        ax.errorbar(
            s.value,
            e.value,
            xerr=[[s.value - s.low], [s.high - s.value]],
            yerr=[[e.value - e.low], [e.high - e.value]],
            fmt="o",
            capsize=2,
            label=name,
        )
    ax.set_xscale("log")
    if metric == RELATIVE_ERROR:
        finite = [abs(v.value) for v in errors.values() if math.isfinite(v.value) and v.value]
        ax.set_yscale("symlog", linthresh=max(1e-6, min(finite) / 2.0) if finite else 1e-4)
    else:
        ax.set_yscale("log")
    below = [
        name
        for name, e in errors.items()
        if name != REFERENCE_NAME and metric == RELATIVE_ERROR and e.value < 0.0
    ]
    if below:  # more accurate than the reference: say why, on the figure
        ax.axhline(0.0, color="k", linewidth=0.6, linestyle=":")
        own = rows.select(robot=robot)
        reasons = [f"{n}{limits_clause(own, n) or ' (limits kept)'}" for n in below]
        ax.text(
            0.01,
            0.01,
            "below the reference (0): "
            + "; ".join(reasons)
            + ".\nThe reference keeps every joint limit and is solved to 1 % of the position "
            "tolerance by a local solver:\na row below it broke a limit, or beat it within "
            "that resolution or where the local solver stopped short.",
            transform=ax.transAxes,
            fontsize=5.5,
            va="bottom",
            wrap=True,
        )
    ax.set_xlabel("median peak joint speed [rad/s]")
    label = "oracle-relative max error" if metric == RELATIVE_ERROR else "max error"
    ax.set_ylabel(f"median {label} [m]")
    ax.legend(fontsize=6)
    ax.set_title(f"{robot}: accuracy vs peak speed (lower-left is better; 95 % CIs)")
    figure.subplots_adjust(left=0.13, right=0.98, bottom=0.12, top=0.9)
    return _save(figure, out, f"pareto-{robot}.png")


#: The run report's stylesheet, plus the study report's verdict box.
_STUDY_CSS = ".verdict{background:#f8fafc;border-left:4px solid #2b5797;padding:.2rem 1rem}"


def render_html(config: StudyConfig, markdown: str, out: Path) -> str:
    """The self-contained HTML page: the Markdown rendered, figures embedded as base64.

    Every name (controllers, robots, generators) reaches the page through
    :func:`otmm_qp.output.escape.escape` (in :func:`otmm_qp.output.markdown.markdown_to_html`).
    """
    from otmm_qp.output.markdown import REPORT_CSS, markdown_to_html

    parts: list[str] = []
    chunk: list[str] = []
    in_verdict = False

    def flush() -> None:
        if chunk:
            body = markdown_to_html("\n".join(chunk))
            parts.append(f'<div class="verdict">{body}</div>' if in_verdict else body)
            chunk.clear()

    for line in markdown.splitlines():
        image = re.fullmatch(r"!\[(.*)\]\((figures/[^)]+)\)", line.strip())
        if image:
            flush()
            parts.append(_figure_html(out, image.group(2), image.group(1)))
        elif line.startswith("#"):
            flush()
            in_verdict = line.strip().startswith("### Verdict")
            chunk.append(line)
            flush()
        else:
            chunk.append(line)
    flush()
    title = escape(f"Study {config.name}")
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>{title}</title><style>{REPORT_CSS}{_STUDY_CSS}</style></head><body>\n"
        + "\n".join(parts)
        + "\n</body></html>\n"
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


def write_study_report(out: Path, highlight: str | None = None) -> tuple[Path, Path]:
    """Write ``study_report.html`` and ``study_report.md`` (and figures) for a study dataset.

    Args:
        out: The study folder.
        highlight: A controller placed as *ours* on each group's Pareto front, or None.

    Raises:
        OtmmError: ``out`` is not a study directory or holds no episodes.
        ConfigError: ``highlight`` names no controller of the study (before any figure).
    """
    out = Path(out)
    config, rows = load_rows(out)
    check_highlight(rows, highlight)
    figures = write_figures(out, rows)
    markdown = render_markdown(config, rows, figures, highlight)
    md_path = out / "study_report.md"
    html_path = out / "study_report.html"
    atomic_write_text(md_path, markdown)
    atomic_write_text(html_path, render_html(config, markdown, out))
    return html_path, md_path
