"""The report composed: the decision per robot first, then the method and the details.

:func:`write_study_report` reads the stored rows, writes the figures, composes the document
(:func:`document`) and renders it to ``study_report.md`` and ``study_report.html``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from otmm_qp.metrics.table import metric as metric_row
from otmm_qp.paths import atomic_write_text
from otmm_qp.studies.decide import GUARANTEE, judge_rows, kind_sentence
from otmm_qp.studies.document import Figure, Heading, Item, to_markdown
from otmm_qp.studies.fronts import GroupFront, counts_sentence, detail_table, summary_table
from otmm_qp.studies.oracle import REFERENCE_NAME
from otmm_qp.studies.report.figures import pareto_path, write_figures
from otmm_qp.studies.report.html import render_html
from otmm_qp.studies.report.lines import ranking_line, verdict_lines
from otmm_qp.studies.report.tables import (
    PAIRED_METRICS,
    bracket_table,
    cause_table,
    generator_table,
    mcnemar_table,
    paired_table,
    sigma_table,
    success_table,
    worst_table,
)
from otmm_qp.studies.rows import Rows, is_reference, load_rows, task_of
from otmm_qp.studies.schema import StudyConfig
from otmm_qp.studies.verdicts import (
    ALPHA,
    RESAMPLES,
    check_highlight,
    study_fronts,
    success_ranking,
)


def render_markdown(
    config: StudyConfig, rows: Rows, figures: Sequence[str], highlight: str | None = None
) -> str:
    """The Markdown report (:func:`document` rendered)."""
    return to_markdown(document(config, rows, figures, highlight))


def document(
    config: StudyConfig, rows: Rows, figures: Sequence[str], highlight: str | None = None
) -> list[Item]:
    """The report: the decision per kind of task first, then the method and details.

    Per robot after the method: bracket → fronts → figure → causes → details.

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
    out: list[Item] = overview[:cut]  # title, description, counts; the answer, the method
    out += [Heading(2, "Decision for the arm"), ""]
    arm = judge_rows(rows.rows, 0, 0)
    for robot in rows.robots():
        lines = (
            [f"- {arm.arm_line(robot)}", *verdict_lines(rows, robot)] if robot in arm.arms else []
        )
        out += [Heading(3, f"Verdict on {robot}", box=True), "", *lines, ""]
    breakdown = [
        f"- {robot} / {kind_sentence(kind, verdict)}"
        for (robot, kind), verdict in sorted(arm.kinds.items())
    ]
    if breakdown:
        out += ["By generator (the task mix, known before a task runs; the same test):", ""]
        out += [*breakdown, ""]
    out += [
        "The first line of each box is the decision for the arm over all its tasks (the "
        "study's task mix). " + GUARANTEE + " The kinds of task "
        "beneath are the offline reference's labels, which a controller cannot know online, "
        "judged by the exact McNemar test (Holm) on the tasks as stored: descriptive, not "
        "corrected for a study that stopped itself.",
        "",
    ]
    out += [Heading(2, "Method"), "", *overview[cut:]]
    out += _fronts_overview(fronts, highlight)
    for robot in rows.robots():
        own = [f for f in fronts if f.robot == robot]
        out += _robot_section(rows, robot, figures, own, highlight)
        out += _front_details(own, highlight)
    table, _ = success_table(rows, None)
    out += [Heading(2, "All robots"), "", table, ""]
    out += [
        Heading(2, "Success rate by robot and generator (95 % Wilson CI)"),
        "",
        generator_table(rows),
        "",
    ]
    rest = [f for f in figures if f not in {pareto_path(r) for r in rows.robots()}]
    if rest:
        out += [Heading(2, "Figures"), "", *[Figure(f, f) for f in rest], ""]
    return out


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


def _overview(config: StudyConfig, rows: Rows) -> list[Item]:
    """Report title, description, what was run, the criteria and the statistics used."""
    competitors = [r for r in rows.rows if not is_reference(r)]
    errors = sum(1 for r in competitors if r.get("status") == "error")
    tasks = len({task_of(r) for r in rows.rows})
    reference = (
        f"Each task's offline-optimal reference ({REFERENCE_NAME} rows) is shown as a row and "
        "a point, "
        "never ranked; accuracy is the oracle-relative error max_error − reference.max_error."
        if rows.has_reference
        else "No offline reference is stored: tasks are judged by the tolerances alone and "
        "accuracy is the max error."
    )
    return [
        Heading(1, f"Study {config.name}"),
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


def _front_details(fronts: Sequence[GroupFront], highlight: str | None) -> list[Item]:
    """Per group of one robot: every row's medians, place on the front and paired tests."""
    out: list[Item] = []
    for front in fronts:
        out += [
            Heading(3, f"{front.robot} / {front.group}: medians, front and paired tests"),
            "",
            detail_table(front, _ours(highlight)),
            "",
        ]
    return out


def _robot_section(
    rows: Rows,
    robot: str,
    figures: Sequence[str],
    fronts: Sequence[GroupFront] = (),
    highlight: str | None = None,
) -> list[Item]:
    """One robot: Pareto fronts, figure, failure causes, worst episodes, tables.

    Its verdict lines open the report (``## Decision per kind of task``).
    """
    out: list[Item] = [Heading(2, robot), ""]
    out += bracket_table(rows, robot)
    if fronts:
        out += [
            Heading(3, f"Pareto fronts on {robot}"),
            "",
            summary_table(fronts, _ours(highlight), rows.information_labels()),
        ]
        out += [""]
    pareto = pareto_path(robot)
    if pareto in figures:
        out += [Figure(pareto, f"Pareto: {robot}"), ""]
    out += cause_table(rows, robot)
    out += worst_table(rows, robot)
    out += [Heading(3, "Success rates and medians"), ""]
    table, rates = success_table(rows, robot)
    out += [table, ""]
    ranking, tests = success_ranking(rows, robot, {n: v[0] for n, v in rates.items()})
    out += [ranking_line(ranking, "success rate", "McNemar test"), ""]
    out += mcnemar_table(tests, robot)
    for paired in (rows.accuracy_metric(), *(m.name for m in PAIRED_METRICS)):
        out += paired_table(rows, robot, paired)
    for metric in ("max_error", "max_joint_speed"):
        out += sigma_table(rows, robot, metric)
    return out


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
    items = document(config, rows, figures, highlight)
    md_path = out / "study_report.md"
    html_path = out / "study_report.html"
    atomic_write_text(md_path, to_markdown(items))
    atomic_write_text(html_path, render_html(config, items, out))
    return html_path, md_path
