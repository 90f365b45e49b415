"""The report's plain-words lines: the verdict per kind of task, the accuracy and a ranking.

Each line renders a typed result of :mod:`otmm_qp.studies.verdicts` (the info side); nothing
here tests or ranks. :func:`verdict_line` renders one group's decision (the module
:mod:`otmm_qp.studies.group_verdict` is a different thing: a controller's place on the fronts).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from otmm_qp.studies.formatting import interval as _interval
from otmm_qp.studies.formatting import p_value as _p
from otmm_qp.studies.formatting import percent as _pct
from otmm_qp.studies.limit_keeping import breaks_clause, limit_breaks
from otmm_qp.studies.rows import Rows
from otmm_qp.studies.sizing import decision_advice
from otmm_qp.studies.verdicts import ALPHA, TaskGroup, decide_group, task_groups
from otmm_qp.studies.verdicts import accuracy_verdict as decide_accuracy

if TYPE_CHECKING:
    from otmm_qp.studies.statistics import Ranked


def verdict_line(group: TaskGroup) -> str:
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


def accuracy_line(rows: Rows, robot: str) -> str:
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


def verdict_lines(rows: Rows, robot: str) -> list[str]:
    """The plain-words verdict lines of ``robot``."""
    lines = [verdict_line(group) for group in task_groups(rows, robot)]
    lines.append(accuracy_line(rows, robot))
    return lines


def ranking_line(ranking: list[Ranked], what: str, test: str) -> str:
    """The ranking sentence: each name with its rank (``=``: a shared rank)."""
    return (
        f"Ranking by {what} (rank = 1 + the number of controllers that beat it in the paired "
        f"{test}, Holm p < {ALPHA:g}; = marks a shared rank, i.e. as many controllers beat "
        "each; it does not say the two are indistinguishable): "
        + ", ".join(f"{r.rank}{'=' if r.tied else ''} {r.name}" for r in ranking)
    )
