"""The report's tables, each a :class:`~otmm_qp.studies.document.Table` item of rendered cells.

The numbers come from :mod:`otmm_qp.studies.verdicts` (rates, tests, bracket, σ curves) or are
counts of the stored rows; this module only lays them out.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from otmm_qp.metrics.table import STUDY_MEDIANS, STUDY_PAIRED, Metric
from otmm_qp.metrics.table import metric as metric_row
from otmm_qp.studies.columns import KEPT_LIMITS, number
from otmm_qp.studies.criteria import FAILURE_CAUSES
from otmm_qp.studies.document import Heading, Item, Table
from otmm_qp.studies.formatting import fmt as _fmt
from otmm_qp.studies.formatting import interval as _interval
from otmm_qp.studies.formatting import p_value as _p
from otmm_qp.studies.formatting import percent as _pct
from otmm_qp.studies.fronts import with_information
from otmm_qp.studies.rows import RELATIVE_ERROR, Rows, is_reference
from otmm_qp.studies.verdicts import (
    bracket_summary,
    generator_rates,
    paired_for,
    sigma_curves,
    success_summary,
)

if TYPE_CHECKING:
    from otmm_qp.studies.statistics import PairedRates


#: Metrics summarised by median + bootstrap interval (rows of the metric table).
MEDIAN_METRICS: tuple[Metric, ...] = tuple(map(metric_row, STUDY_MEDIANS))


#: Metrics compared pairwise after the headline accuracy (rows of the metric table).
PAIRED_METRICS: tuple[Metric, ...] = tuple(map(metric_row, STUDY_PAIRED))


def _median_metrics(rows: Rows) -> tuple[Metric, ...]:
    if rows.has_reference:
        return (metric_row(RELATIVE_ERROR), *MEDIAN_METRICS)
    return MEDIAN_METRICS


def success_table(
    rows: Rows, robot: str | None
) -> tuple[Table, dict[str, tuple[float, float, float]]]:
    """The table of success rates and medians, and ``controller → (rate, low, high)``.

    The reference (``oracle``) is the last row, without a success rate. Each row name carries
    its information class when the study mixes several (:meth:`Rows.information_labels`).
    """
    metrics = _median_metrics(rows)
    headers = ["controller", "episodes", "errors", "success [95 % CI]"]
    headers += [f"median {m.heading} (95 % CI)" for m in metrics]
    cells_of: list[list[str]] = []
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
        cells_of.append(cells)
    return Table(headers, cells_of), rates


def generator_table(rows: Rows) -> Table:
    """Success rate [CI] per controller (rows) and robot/generator (columns)."""
    groups, table = generator_rates(rows)
    return Table(
        ["controller", *(f"{robot} {gen}" for robot, gen in groups)],
        [
            [
                name,
                *(f"{100 * r:.0f} % [{100 * low:.0f}, {100 * high:.0f}]" for r, low, high in cells),
            ]
            for name, cells in table.items()
        ],
    )


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
    ]
    headers = ["kind of task", "tasks", "achievable / unachievable / undecided / failed"]
    headers += ["median gap", "90th percentile gap", "no known path passes"]
    cells = [
        [row.kind, str(row.tasks), "/".join(str(c) for c in row.counts)]
        + [_fmt(row.median_gap), _fmt(row.p90_gap), str(row.unpassed)]
        for row in summary
    ]
    return [*out, Table(headers, cells), ""]


def cause_table(rows: Rows, robot: str) -> list[Item]:
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
    ]
    cells: list[list[str]] = []
    generators = list(dict.fromkeys(r["generator"] for r in rows.select(robot=robot)))
    for name in rows.controllers():
        for gen in generators:
            selected = rows.select(controller=name, robot=robot, generator=gen)
            if not selected:
                continue
            wins = sum(1 for r in selected if r["success"])
            counts = [sum(1 for r in selected if c in r["failure_causes"]) for c in FAILURE_CAUSES]
            cells.append([name, gen, str(len(selected)), _pct(wins / len(selected))])
            cells[-1] += [str(c) for c in counts]
    headers = ["controller", "generator", "episodes", "success", *FAILURE_CAUSES]
    return [*out, Table(headers, cells), ""]


def worst_table(rows: Rows, robot: str) -> list[Item]:
    """Each controller's worst episode by the headline accuracy, with its drill-down id."""
    metric = rows.accuracy_metric()
    out: list[Item] = [
        Heading(3, f"Worst episode of each controller on {robot} (by {metric})"),
        "",
        "`otmm-qp study show DIR --episode ID` prints an episode and writes a config that "
        "re-runs it.",
        "",
    ]
    cells: list[list[str]] = []
    for name in rows.controllers():
        ran = [
            r for r in rows.select(controller=name, robot=robot) if math.isfinite(number(r, metric))
        ]
        if not ran:
            continue
        worst = max(ran, key=lambda r: (number(r, metric), str(r.get("episode_key"))))
        task = worst.get("task_id") or f"{worst['generator']}/{worst['task_index']}"
        cells.append([name, f"`{worst['episode_id']}`", str(task), _fmt(number(worst, metric))])
        cells[-1] += [_fmt(number(worst, "max_joint_speed"))]
        cells[-1] += [", ".join(worst["failure_causes"]) or "none"]
    headers = ["controller", "id", "task", f"{metric} [m]", "peak joint speed [rad/s]"]
    return [*out, Table([*headers, "failure causes"], cells), ""]


def mcnemar_table(tests: list[PairedRates], robot: str) -> list[Item]:
    """The exact McNemar tests of success on the same tasks (Holm p < 0.05: ``*``)."""
    headers = ["A", "B", "tasks", "A only", "B only", "both", "p", "Holm p", "favours"]
    cells = [
        [t.a, t.b, str(t.pairs), str(t.a_only), str(t.b_only), str(t.both), _p(t.p_value)]
        + [_p(t.p_holm) + (" *" if t.significant else ""), t.favoured or "neither"]
        for t in tests
    ]
    return [
        Heading(3, f"Paired success on {robot} (exact McNemar on the same tasks)"),
        "",
        Table(headers, cells),
        "",
    ]


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


def paired_table(rows: Rows, robot: str, metric: str) -> list[Item]:
    """The paired comparisons of ``metric`` on ``robot`` (Holm p < 0.05: ``*``)."""
    out: list[Item] = [
        Heading(3, f"Paired comparisons on {robot}: {metric} (lower wins)"),
        "",
        "*favours*: the side the signed-rank sums favour (W⁻ > W⁺: A); ⚠ where the strict "
        "counts or the median difference point the other way.",
        "",
    ]
    if metric == RELATIVE_ERROR:
        out[3:3] = [_undefined_line(rows, robot), ""]
    headers = ["A", "B", "tasks", "A lower", "ties", "A higher", "median A−B [95 % CI]"]
    headers += ["Hodges–Lehmann", "Wilcoxon p", "Holm p", "favours"]
    cells = [
        [r.a, r.b, str(r.pairs), str(r.lower), str(r.ties), str(r.higher)]
        + [_interval(r.median_difference), _fmt(r.hodges_lehmann), _p(r.p_value), _p(r.p_holm)]
        + [
            (r.favoured or "neither")
            + (" *" if r.significant else "")
            + ("" if r.consistent else " ⚠")
        ]
        for r in paired_for(rows, robot, metric)
    ]
    return [*out, Table(headers, cells), ""]


def sigma_table(rows: Rows, robot: str, metric: str) -> list[Item]:
    """``metric``'s binned medians vs σ_min at closest approach (or nothing)."""
    centres, curves = sigma_curves(rows, robot, metric)
    if not curves:
        return []
    cells = [
        [name, *(f"{_fmt(m)} (n={c})" for m, c in zip(medians, counts, strict=True))]
        for name, (medians, counts) in curves.items()
    ]
    return [
        Heading(3, f"{robot}: median {metric} vs σ_min at closest approach"),
        "",
        Table(["controller", *(f"σ≈{_fmt(c, 2)}" for c in centres)], cells),
        "",
    ]
