"""Study report: verdicts, Pareto figure, failure causes, then the detailed tables.

``write_study_report(DIR)`` reads ``DIR/study.json`` and the Parquet dataset and writes
``DIR/study_report.md``, ``DIR/study_report.html`` (the run report's style, figures embedded)
and ``DIR/figures/*.png``. Every number in them is computed here from the stored rows.

Per robot the report leads with the verdict in plain words — which controller to pick for
singular crossings, for tasks certified unachievable, for undecided ones (the reference's
bracket labels) and for limit-bound motion, each backed by the
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
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from otmm_qp.metrics.table import STUDY_MEDIANS, STUDY_PAIRED, Metric
from otmm_qp.metrics.table import metric as metric_row
from otmm_qp.output.escape import escape
from otmm_qp.paths import atomic_write_bytes, atomic_write_text, ensure_inside, safe_name
from otmm_qp.studies.columns import KEPT_LIMITS, number
from otmm_qp.studies.criteria import FAILURE_CAUSES
from otmm_qp.studies.decide import GUARANTEE, judge_rows, kind_sentence
from otmm_qp.studies.document import Figure, Heading, Item, to_html, to_markdown
from otmm_qp.studies.formatting import fmt as _fmt
from otmm_qp.studies.formatting import interval as _interval
from otmm_qp.studies.formatting import p_value as _p
from otmm_qp.studies.formatting import percent as _pct
from otmm_qp.studies.fronts import (
    GroupFront,
    counts_sentence,
    detail_table,
    summary_table,
    with_information,
)
from otmm_qp.studies.limit_keeping import breaks_clause, limit_breaks, limits_clause
from otmm_qp.studies.oracle import REFERENCE_NAME
from otmm_qp.studies.rows import RELATIVE_ERROR, Rows, is_reference, load_rows, task_of
from otmm_qp.studies.schema import StudyConfig
from otmm_qp.studies.sizing import decision_advice
from otmm_qp.studies.verdicts import (
    ALPHA,
    RESAMPLES,
    TaskGroup,
    bracket_summary,
    check_highlight,
    decide_group,
    generator_rates,
    median_intervals,
    paired_for,
    sigma_curves,
    study_fronts,
    success_ranking,
    success_summary,
    task_groups,
)
from otmm_qp.studies.verdicts import accuracy_verdict as decide_accuracy

if TYPE_CHECKING:
    from otmm_qp.studies.statistics import PairedRates, Ranked

#: Metrics summarised by median + bootstrap interval (rows of the metric table).
MEDIAN_METRICS: tuple[Metric, ...] = tuple(map(metric_row, STUDY_MEDIANS))
#: Metrics compared pairwise after the headline accuracy (rows of the metric table).
PAIRED_METRICS: tuple[Metric, ...] = tuple(map(metric_row, STUDY_PAIRED))


def _is_oracle(row: dict[str, Any]) -> bool:
    return is_reference(row)


def _known(value: Any) -> bool:
    return value is not None and not (isinstance(value, float) and math.isnan(value))


_value = number


def _task(row: dict[str, Any]) -> object:
    return task_of(row)


def _median_metrics(rows: Rows) -> tuple[Metric, ...]:
    if rows.has_reference:
        return (metric_row(RELATIVE_ERROR), *MEDIAN_METRICS)
    return MEDIAN_METRICS


def success_table(
    rows: Rows, robot: str | None
) -> tuple[list[str], dict[str, tuple[float, float, float]]]:
    """Markdown lines of success rates and medians, and ``controller → (rate, low, high)``.

    The reference (``oracle``) is the last row, without a success rate. Each row name carries
    its information class when the study mixes several (:meth:`Rows.information_labels`).
    """
    metrics = _median_metrics(rows)
    header = (
        "| controller | episodes | errors | success [95 % CI] | "
        + " | ".join(f"median {m.heading} (95 % CI)" for m in metrics)
        + " |"
    )
    lines = [header, "|" + "---|" * (4 + len(metrics))]
    rates: dict[str, tuple[float, float, float]] = {}
    labels = rows.information_labels()
    for line in success_summary(rows, robot, [m.name for m in metrics]):
        if line.rate is None:
            rate = "reference (not ranked)"
        else:
            rates[line.controller] = (line.rate, line.low, line.high)
            rate = f"{100 * line.rate:.1f} % [{100 * line.low:.1f}, {100 * line.high:.1f}]"
        cells = [with_information(line.controller, labels), str(line.episodes)]
        cells += [str(line.errors), rate]
        cells += [_interval(m) for m in line.medians]
        lines.append("| " + " | ".join(cells) + " |")
    return lines, rates


def generator_table(rows: Rows) -> list[str]:
    """Markdown table: success rate [CI] per controller (rows) and robot/generator (columns)."""
    groups, table = generator_rates(rows)
    lines = [
        "| controller | " + " | ".join(f"{robot} {gen}" for robot, gen in groups) + " |",
        "|---|" + "---|" * len(groups),
    ]
    for name, cells in table.items():
        shown = [f"{100 * r:.0f} % [{100 * low:.0f}, {100 * high:.0f}]" for r, low, high in cells]
        lines.append(f"| {name} | " + " | ".join(shown) + " |")
    return lines


def bracket_table(rows: Rows, robot: str) -> list[Item]:
    """The reference's bracket per kind of task (:func:`.verdicts.bracket_summary`)."""
    summary = bracket_summary(rows, robot)
    if not summary:
        return []
    out: list[Item] = [
        Heading(3, f"Reference bracket on {robot}"),
        "",
        "Per kind of task: the reference's labels (achievable: a stored path meets every "
        "tolerance within every limit; unachievable: its certified lower bound exceeds a "
        "tolerance; undecided: neither) and the gap upper − lower of its bracket of the "
        "min-max error, in tolerances (0: the optimum is pinned); and on how many tasks no "
        "known path passes the task's criteria (no controller row, not the reference's own).",
        "",
        "| kind of task | tasks | achievable / unachievable / undecided / failed "
        "| median gap | 90th percentile gap | no known path passes |",
        "|---|---|---|---|---|---|",
    ]
    for row in summary:
        counts = "/".join(str(c) for c in row.counts)
        out.append(
            f"| {row.kind} | {row.tasks} | {counts} | {_fmt(row.median_gap)} | "
            f"{_fmt(row.p90_gap)} | {row.unpassed} |"
        )
    return [*out, ""]


def group_verdict(group: TaskGroup) -> str:
    """One plain-words verdict line of :func:`~otmm_qp.studies.verdicts.decide_group`.

    An undecided group (rows not separated) says about how many tasks a decision would need
    (:func:`~otmm_qp.studies.sizing.decision_advice`), never a bare "none is to be preferred".
    """
    verdict = decide_group(group)
    head = f"- **{group.label.capitalize()}** ({verdict.tasks} tasks: {group.reading}): "
    rates = verdict.rates
    if verdict.outcome == "no tasks":
        return head + "no such tasks in this study."
    if verdict.outcome == "single":
        return head + f"only {verdict.pick} ran (success {_pct(rates[str(verdict.pick)])})."
    if verdict.outcome == "none succeeds":
        return head + "no controller succeeds on any of them."
    if verdict.outcome == "not separated":
        return (
            head
            + "no paired test separates the controllers, so none is to be preferred here ("
            + ", ".join(
                f"{r.name} {_pct(rates[r.name])}"
                for r in sorted(verdict.ranking, key=lambda r: (-rates[r.name], r.name))
            )
            + "); "
            + decision_advice(str(verdict.leader), verdict.tests)
            + "."
        )
    best = str(verdict.pick)
    broken, runs = limit_breaks(group.rows, best)
    decided = not verdict.not_separated and verdict.beaten == len(rates) - 1
    if not decided or 2 * broken > runs:  # bold only a decided pick that keeps the limits
        text = head + f"leader {best} (success {_pct(rates[best])}; not a decision"
        text += (
            f": it breaks the arm's limits on {broken} of {runs} episodes)"
            if 2 * broken > runs
            else ": it does not beat every other row)"
        )
    else:
        text = head + f"pick **{best}** (success {_pct(rates[best])})"
    if verdict.not_separated:
        text += "; not separated from it by the paired test: " + ", ".join(
            f"{name} ({_pct(rates[name])})" for name in verdict.not_separated
        )
        text += "; " + decision_advice(best, verdict.tests)
    closest = verdict.closest
    if closest is not None:
        text += (
            f"; it beats {verdict.beaten} of the others, the closest {closest.name} "
            f"({_pct(rates[closest.name])}: {best} alone succeeds on {closest.pick_only} tasks, "
            f"{closest.name} alone on {closest.other_only}, McNemar Holm p = "
            f"{_p(closest.p_holm)})"
        )
    return text + "."


def accuracy_verdict(rows: Rows, robot: str) -> str:
    """The verdict line of :func:`~otmm_qp.studies.verdicts.accuracy_verdict`."""
    verdict = decide_accuracy(rows, robot)
    label = "oracle-relative max error" if verdict.relative else "max error"
    if not verdict.top:
        return f"- **Accuracy ({label})**: no finite values."
    top = verdict.top
    shown = ", ".join(
        f"{n} {_interval(verdict.medians[n])} m{breaks_clause(*verdict.breaks.get(n, (0, 0)))}"
        for n in top[:4]
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
        lines = [f"- {arm.arm_line(robot)}", *_verdicts(rows, robot)] if robot in arm.arms else []
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
    lines, _ = success_table(rows, None)
    out += [Heading(2, "All robots"), "", *lines, ""]
    out += [
        Heading(2, "Success rate by robot and generator (95 % Wilson CI)"),
        "",
        *generator_table(rows),
        "",
    ]
    rest = [f for f in figures if f not in {_pareto_path(r) for r in rows.robots()}]
    if rest:
        out += [Heading(2, "Figures"), "", *[Figure(f, f) for f in rest], ""]
    return out


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


def _overview(config: StudyConfig, rows: Rows) -> list[Item]:
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
            *summary_table(fronts, _ours(highlight), rows.information_labels()),
        ]
        out += [""]
    pareto = _pareto_path(robot)
    if pareto in figures:
        out += [Figure(pareto, f"Pareto: {robot}"), ""]
    out += _cause_table(rows, robot)
    out += _worst_table(rows, robot)
    out += [Heading(3, "Success rates and medians"), ""]
    lines, rates = success_table(rows, robot)
    out += lines + [""]
    ranking, tests = success_ranking(rows, robot, {n: v[0] for n, v in rates.items()})
    out += [_ranking_line(ranking, "success rate", "McNemar test"), ""]
    out += _mcnemar_table(tests, robot)
    for paired in (rows.accuracy_metric(), *(m.name for m in PAIRED_METRICS)):
        out += _paired_table(rows, robot, paired)
    for metric in ("max_error", "max_joint_speed"):
        out += _sigma_table(rows, robot, metric)
    return out


def _cause_table(rows: Rows, robot: str) -> list[Item]:
    """Episodes failing each criterion, per controller × generator (one can fail several)."""
    out: list[Item] = [
        Heading(3, f"Failure causes on {robot}"),
        "",
        "Episodes failing each criterion (an episode can fail several): *error* = tolerance "
        "(achievable tasks) or graceful error bound (unachievable), *speed* = speed bound, "
        "*position_limit* = a joint left its limits, *blow_up*, *stuck* = stopped early, "
        "*chatter* (unachievable tasks), *interface_abort* = the commanded acceleration or "
        "jerk passed the arm interface's thresholds, *run_error* = never ran.",
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


def _worst_table(rows: Rows, robot: str) -> list[Item]:
    """Each controller's worst episode by the headline accuracy, with its drill-down id."""
    metric = rows.accuracy_metric()
    out: list[Item] = [
        Heading(3, f"Worst episode of each controller on {robot} (by {metric})"),
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


def _mcnemar_table(tests: list[PairedRates], robot: str) -> list[Item]:
    out: list[Item] = [
        Heading(3, f"Paired success on {robot} (exact McNemar on the same tasks)"),
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


def _undefined_line(rows: Rows, robot: str) -> str:
    """Which rows have no oracle-relative error on ``robot``: those that broke a limit."""
    own = [r for r in rows.select(robot=robot) if not is_reference(r)]
    counts = {
        name: sum(1 for r in own if r["controller"] == name and not r.get(KEPT_LIMITS))
        for name in rows.controllers()
    }
    broken = [f"{name} {k} of {sum(r['controller'] == name for r in own)}"
              for name, k in counts.items() if k]  # fmt: skip
    return (
        "The oracle-relative error is defined only on rows that kept every limit "
        "(`kept_limits`): the reference is the optimum within the limits. Null, so left out of "
        "the pairs: " + ("; ".join(broken) if broken else "none") + "."
    )


def _paired_table(rows: Rows, robot: str, metric: str) -> list[Item]:
    """Markdown table of the paired comparisons of ``metric`` on ``robot`` (Holm p < 0.05: *)."""
    out: list[Item] = [
        Heading(3, f"Paired comparisons on {robot}: {metric} (lower wins)"),
        "",
        "*favours*: the side the signed-rank sums favour (W⁻ > W⁺: A); ⚠ where the strict "
        "counts or the median difference point the other way.",
        "",
        "| A | B | tasks | A lower | ties | A higher | median A−B [95 % CI] | "
        "Hodges–Lehmann | Wilcoxon p | Holm p | favours |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    if metric == RELATIVE_ERROR:
        out[3:3] = [_undefined_line(rows, robot), ""]
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


def _sigma_table(rows: Rows, robot: str, metric: str) -> list[Item]:
    """Markdown table of ``metric``'s binned medians vs σ_min at closest approach (or none)."""
    centres, curves = sigma_curves(rows, robot, metric)
    if not curves:
        return []
    out: list[Item] = [
        Heading(3, f"{robot}: median {metric} vs σ_min at closest approach"),
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
    axis, as medians can be 0; defined only on rows that kept every limit, so ``≥ 0``: the
    note below the reference can only come from older stored rows), or the max error (log
    axis) when no reference is stored.
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


def render_html(config: StudyConfig, items: Sequence[Item], out: Path) -> str:
    """The self-contained HTML page of the report's items, figures embedded as base64.

    Every name (controllers, robots, generators) reaches the page through
    :func:`otmm_qp.output.escape.escape` (in :func:`otmm_qp.output.markdown.markdown_to_html`).
    """
    from otmm_qp.output.markdown import REPORT_CSS

    return to_html(
        items,
        f"Study {config.name}",
        REPORT_CSS + _STUDY_CSS,
        lambda figure: _figure_html(out, figure.path, figure.caption),
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
    items = document(config, rows, figures, highlight)
    md_path = out / "study_report.md"
    html_path = out / "study_report.html"
    atomic_write_text(md_path, to_markdown(items))
    atomic_write_text(html_path, render_html(config, items, out))
    return html_path, md_path
