r"""Where one controller sits on a study's Pareto fronts: a thin command over ``fronts``.

The fronts, the paired tests and the criterion are those of :mod:`otmm_qp.studies.fronts`,
which the study report uses too. Per robot × generator (default) or per kind of task pooled
over the study's robots (``--kinds``: singular crossings, unachievable (certified), undecided
and limit-bound motion as the report's verdicts choose them from the reference's bracket, plus
held targets and reachable random targets by generator; a task can be in several)::

    otmm-qp study verdict DIR --ours NAME [--kinds] [--out FILE]

Objectives: the headline accuracy (oracle-relative max error [m], or max error without a
reference), the peak joint speed and the largest one-step jump [rad/s].
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from otmm_qp.metrics.table import metric
from otmm_qp.output.markdown import table_markdown
from otmm_qp.studies.document import Heading, Item, Table, to_markdown
from otmm_qp.studies.fronts import (
    GroupFront,
    RowFront,
    counts_sentence,
    detail_table,
    front_of,
    summary_table,
)
from otmm_qp.studies.limit_keeping import limits_clause
from otmm_qp.studies.oracle import REFERENCE_NAME
from otmm_qp.studies.rows import Rows, task_key
from otmm_qp.studies.verdicts import RESAMPLES, objectives, task_groups

#: Kinds of task chosen by generator (the reference-chosen ones come from ``task_groups``).
GENERATOR_KINDS: tuple[tuple[str, str], ...] = (
    ("held targets", "held_target"),
    ("reachable random", "random_reachable"),
)


def kind_rows(rows: Rows) -> dict[str, list[dict[str, Any]]]:
    """The online rows of each kind of task, pooled over the study's robots.

    A task can be in several kinds (see the module docstring).
    """
    pooled: dict[str, list[dict[str, Any]]] = {}
    for robot in rows.robots():
        for group in task_groups(rows, robot):
            pooled.setdefault(group.label, []).extend(group.rows)
    for label, generator in GENERATOR_KINDS:
        pooled[label] = [
            r for r in rows.select(generator=generator) if r["controller"] != REFERENCE_NAME
        ]
    return pooled


def kind_fronts(rows: Rows) -> list[GroupFront]:
    """The front of each kind of task, pooled over the study's robots (see the docstring)."""
    pooled = kind_rows(rows)
    robots = ", ".join(rows.robots())
    return [
        front_of(robots, label, selected, objectives(rows), task_key, RESAMPLES)
        for label, selected in pooled.items()
        if selected
    ]


def _medians(row: RowFront) -> str:
    return " / ".join(f"{v:.3g}" if math.isfinite(v) else "–" for v in row.medians)


def _verdict(row: RowFront) -> str:
    """The outcome (Holm over all pairs) with the evidence of each significant difference."""
    out = []
    for outcome, word in (("worse", "loses"), ("better", "wins")):
        parts = [
            f"{metric(c.objective).label} vs {c.other} (Holm p = {c.p_holm['all']:.2g})"
            for c in row.comparisons
            if c.outcome() == outcome
        ]
        if parts:
            out.append(f"{word} on " + ", ".join(parts))
    return "; ".join(out) or "no significant difference from the best others"


def kinds_table(
    fronts: Sequence[GroupFront],
    ours: str,
    kinds: Mapping[str, list[dict[str, Any]]] | None = None,
) -> list[str]:
    """Markdown lines: per kind of task the most accurate and the calmest front rows, and ours.

    With the rows of each kind (``kinds``, :func:`kind_rows`), the most accurate pick says in
    its cell how often it broke the arm's limits (:mod:`otmm_qp.studies.limit_keeping`).
    """
    heads = " / ".join(metric(m).label for m in fronts[0].objectives) if fronts else ""
    headers = ["task kind (tasks)", f"most accurate (medians {heads})", "lowest peak speed"]
    headers += [f"`{ours}`", "meets the criterion (Holm: all pairs / best others)"]
    lines: list[list[str]] = []
    for g in fronts:
        cells = []
        for k in (0, 1):
            name = g.best_on(k)
            row = g.row(name) if name is not None else None
            note = limits_clause(kinds.get(g.group, []), row.name) if kinds and row else ""
            cells.append(f"{row.name} ({_medians(row)}){note}" if row is not None else "–")
        mine = g.row(ours)
        if mine is None:
            where = "did not run"
        else:
            if mine.on_front:
                place = "on the front"
            elif mine.dominated_by:
                place = "dominated by " + ", ".join(mine.dominated_by)
            else:  # a median is undefined (e.g. no oracle-relative error: limits broken)
                place = "not placed (an objective has no median)"
            where = f"{_medians(mine)}; {place}; {_verdict(mine)}"
        meeting = " / ".join(", ".join(g.meeting(f)) or "none" for f in ("all", "best"))
        lines.append([f"{g.group} ({g.tasks})", cells[0], cells[1], where, meeting])
    return table_markdown(Table(headers, lines))


def render(
    fronts: Sequence[GroupFront],
    ours: str,
    kinds: bool = False,
    rows: Mapping[str, list[dict[str, Any]]] | None = None,
) -> str:
    """The Markdown text: the counts, the summary (or kinds) table, then each group's details.

    ``rows``: each kind's rows, for the limits note of the kinds table.
    """

    def mine(name: str) -> bool:
        return name == ours

    items: list[Item] = [counts_sentence(fronts, mine), ""]
    if kinds:
        return to_markdown([*items, *kinds_table(fronts, ours, rows)])
    items += [summary_table(fronts, mine), ""]
    for g in fronts:
        items += [Heading(3, f"{g.robot} / {g.group}"), "", detail_table(g, mine), ""]
    return to_markdown(items)
