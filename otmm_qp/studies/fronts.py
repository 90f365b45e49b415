r"""Pareto fronts of a study's task groups, and whether any row dominates the others there.

For a group of tasks (a robot × generator, or a kind of task) and objectives
:math:`f_1, \dots, f_m`, all minimised — by default the oracle-relative max error
``max_error − reference.max_error`` [m], the peak joint speed
:math:`\max_{k \ge 1}\|\dot q_k\|_\infty` [rad/s] and the largest one-step jump
:math:`\max_k \|\dot q_k - \dot q_{k-1}\|_\infty` [rad/s] — every online row *R* (the
offline reference is not a competitor) has the medians
:math:`M_R = (\operatorname{median} f_1, \dots, \operatorname{median} f_m)` over the group's
episodes (runs that errored count as missing).

* *R* is **on the front** when its medians are finite and no other row *S* has
  :math:`M_S \le M_R` everywhere and :math:`<` somewhere
  (:func:`otmm_qp.output.pareto.dominates`); a dominated row is listed with the front rows
  that dominate it.
* Per objective *k*, *R* is compared with the **best other row**
  :math:`B_k = \arg\min_{S \ne R} \operatorname{median} f_k` by the paired Wilcoxon
  signed-rank test on the tasks both ran: ``better`` when the Holm-adjusted p < α and the
  test favours *R* (:attr:`PairedResult.favoured`), ``worse`` when it favours :math:`B_k`,
  else ``tie``.
* *R* **meets the criterion** of issue 20 when it is worse on no objective and better on at
  least one.

"Paired test, Holm" has two readings; both are computed and named (:data:`FAMILIES`):
``all`` — Holm over every test of *R* against every other row on every objective,
:math:`m(n-1)` tests for *n* rows (the stricter family; the first ``group_verdict`` runs used
it); ``best`` — Holm over *R*'s *m* tests against the :math:`B_k` only.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from otmm_qp.exceptions import ConfigError
from otmm_qp.metrics.table import metric
from otmm_qp.output.pareto import dominates
from otmm_qp.studies.columns import number
from otmm_qp.studies.document import Table
from otmm_qp.studies.formatting import fmt as _fmt
from otmm_qp.studies.formatting import p_value as _p
from otmm_qp.studies.oracle import REFERENCE_NAME
from otmm_qp.studies.statistics import ALPHA, PairedResult, holm, paired_test, wilcoxon_p

#: The two readings of the Holm family (see the module docstring); the first is the default.
FAMILIES: tuple[str, ...] = ("all", "best")
#: Outcomes of one comparison.
OUTCOMES: tuple[str, ...] = ("better", "tie", "worse")

Row = dict[str, Any]
TaskKey = Callable[[Row], Hashable]


@dataclass(frozen=True)
class Comparison:
    """A row against the best other row on one objective.

    Attributes:
        objective: Column name (a row of the metric table).
        other: The other row of lowest median on it.
        result: The paired test, ``a`` = the row, ``b`` = ``other`` (``p_holm`` unset).
        p_holm: Holm-adjusted p per family name of :data:`FAMILIES`.
    """

    objective: str
    other: str
    result: PairedResult
    p_holm: Mapping[str, float]

    def outcome(self, family: str = FAMILIES[0], alpha: float = ALPHA) -> str:
        """``better``, ``worse`` or ``tie`` under the Holm family ``family``."""
        if not self.p_holm[family] < alpha or self.result.favoured is None:
            return "tie"
        return "better" if self.result.favoured == self.result.a else "worse"


@dataclass(frozen=True)
class RowFront:
    """One row of a group: its medians, its place on the front, its paired comparisons.

    Attributes:
        name: Controller name.
        medians: Median of each objective, shape ``(m,)`` (NaN: no finite value).
        dominated_by: The front rows whose medians dominate this row's.
        comparisons: One :class:`Comparison` per objective with another finite row.
    """

    name: str
    medians: tuple[float, ...]
    dominated_by: tuple[str, ...]
    comparisons: tuple[Comparison, ...]

    @property
    def on_front(self) -> bool:
        """Finite medians that no other row's dominate."""
        return all(math.isfinite(v) for v in self.medians) and not self.dominated_by

    def outcomes(self, family: str = FAMILIES[0]) -> tuple[str, ...]:
        """The outcome of each comparison under ``family``."""
        return tuple(c.outcome(family) for c in self.comparisons)

    def meets(self, family: str = FAMILIES[0]) -> bool:
        """No objective worse, at least one better (the issue's criterion)."""
        outcomes = self.outcomes(family)
        return "worse" not in outcomes and "better" in outcomes

    def verdict(self, family: str = FAMILIES[0]) -> str:
        """``dominates``, ``not worse`` or ``loses on <objectives>``."""
        worse = [c.objective for c in self.comparisons if c.outcome(family) == "worse"]
        if worse:
            return "loses on " + ", ".join(worse)
        return "dominates" if self.meets(family) else "not worse"


@dataclass(frozen=True)
class GroupFront:
    """The front of one task group.

    Attributes:
        robot: Robot name (or ``all robots`` for a pooled group).
        group: Generator name or kind of task.
        tasks: Distinct tasks (task and loop mode) of the group.
        objectives: The objective columns, in order.
        rows: One :class:`RowFront` per online row, in first-seen order.
    """

    robot: str
    group: str
    tasks: int
    objectives: tuple[str, ...]
    rows: tuple[RowFront, ...]

    def row(self, name: str) -> RowFront | None:
        """The row of ``name``, or None when it did not run in the group."""
        return next((r for r in self.rows if r.name == name), None)

    @property
    def front(self) -> tuple[str, ...]:
        """Names of the rows on the front."""
        return tuple(r.name for r in self.rows if r.on_front)

    def meeting(self, family: str = FAMILIES[0]) -> tuple[str, ...]:
        """Names of the rows meeting the criterion under ``family``."""
        return tuple(r.name for r in self.rows if r.meets(family))

    def best_on(self, k: int) -> str | None:
        """The row of lowest median on objective ``k``, ties broken by the other objectives.

        The lexicographic minimum (objective ``k`` first, then the others in order) among the
        rows with finite medians: always on the front; None when no row has them.
        """
        finite = [r for r in self.rows if all(math.isfinite(v) for v in r.medians)]
        if not finite:
            return None
        return min(finite, key=lambda r: (r.medians[k], *r.medians)).name

    @property
    def best_on_all(self) -> str | None:
        """A row holding the lowest median of every objective, or None."""
        rows = {r.name: r for r in self.rows}
        for name in {self.best_on(k) for k in range(len(self.objectives))} - {None}:
            medians = rows[str(name)].medians
            if all(
                all(medians[k] <= r.medians[k] for r in self.rows if math.isfinite(r.medians[k]))
                for k in range(len(self.objectives))
            ):
                return str(name)
        return None


def row_value(row: Row, name: str) -> float:
    """A row's numeric ``name`` (:func:`.columns.number`); NaN when the run errored."""
    return math.nan if row.get("status") == "error" else number(row, name)


def _values(rows: Iterable[Row], objective: str, key: TaskKey) -> dict[str, dict[Hashable, float]]:
    """``controller → {task key → value}`` of the online rows."""
    out: dict[str, dict[Hashable, float]] = {}
    for row in rows:
        if row["controller"] != REFERENCE_NAME:
            out.setdefault(row["controller"], {})[key(row)] = row_value(row, objective)
    return out


def _median(values: Mapping[Hashable, float]) -> float:
    data = np.array(list(values.values()), dtype=float)
    data = data[~np.isnan(data)]
    return float(np.median(data)) if data.size else math.nan


def _paired(
    mine: Mapping[Hashable, float], theirs: Mapping[Hashable, float]
) -> tuple[np.ndarray, np.ndarray]:
    keys = sorted(set(mine) & set(theirs), key=repr)
    return np.array([mine[k] for k in keys]), np.array([theirs[k] for k in keys])


def front_of(
    robot: str,
    group: str,
    rows: Sequence[Row],
    objectives: Sequence[str],
    key: TaskKey,
    resamples: int = 2000,
) -> GroupFront:
    """The :class:`GroupFront` of one group's episode rows (see the module docstring).

    Args:
        robot: Label of the robot (or robots) of the group.
        group: Label of the group.
        rows: The group's episode rows (the reference rows are skipped).
        objectives: Minimised columns, each a row of the metric table with
            ``lower_is_better``.
        key: The task an episode ran on (rows with the same key are paired).
        resamples: Bootstrap resamples of each comparison's median difference.

    Raises:
        ConfigError: An objective that is not a metric or not minimised.
    """
    for name in objectives:
        if metric(name).lower_is_better is not True:
            raise ConfigError("objectives", f"{name!r} is not a lower-is-better metric")
    values = [_values(rows, m, key) for m in objectives]
    names = list(values[0])
    medians = {n: tuple(_median(v[n]) for v in values) for n in names}
    raw: dict[tuple[int, frozenset[str]], float] = {}
    for k, per in enumerate(values):
        for i, a in enumerate(names):
            for b in names[i + 1 :]:
                p = wilcoxon_p(*_paired(per[a], per[b]))
                raw[(k, frozenset((a, b)))] = p if math.isfinite(p) else 1.0
    finite = [n for n in names if all(math.isfinite(v) for v in medians[n])]
    dominated = {
        n: [s for s in finite if s != n and dominates(medians[s], medians[n])] for n in finite
    }
    front = [n for n in finite if not dominated[n]]
    out = []
    for name in names:
        family = [(k, o) for k in range(len(objectives)) for o in names if o != name]
        all_holm = dict(
            zip(family, holm([raw[(k, frozenset((name, o)))] for k, o in family]), strict=True)
        )
        chosen: list[tuple[int, str]] = []
        for k in range(len(objectives)):
            others = [o for o in names if o != name and math.isfinite(medians[o][k])]
            if others:
                chosen.append((k, min(others, key=lambda o: medians[o][k])))
        best_holm = holm([raw[(k, frozenset((name, o)))] for k, o in chosen])
        comparisons = tuple(
            Comparison(
                objectives[k],
                other,
                paired_test(name, other, *_paired(values[k][name], values[k][other]), 0, resamples),
                {"all": all_holm[(k, other)], "best": p_best},
            )
            for (k, other), p_best in zip(chosen, best_holm, strict=True)
        )
        by = tuple(f for f in front if name in dominated and f in dominated[name])
        out.append(RowFront(name, medians[name], by, comparisons))
    tasks = len({key(r) for r in rows if r["controller"] != REFERENCE_NAME})
    return GroupFront(robot, group, tasks, tuple(objectives), tuple(out))


def group_fronts(
    rows: Sequence[Row], objectives: Sequence[str], key: TaskKey, resamples: int = 2000
) -> list[GroupFront]:
    """:func:`front_of` every robot × generator group, in first-seen order."""
    groups: dict[tuple[str, str], list[Row]] = {}
    for row in rows:
        groups.setdefault((row["robot"], row["generator"]), []).append(row)
    return [
        front_of(robot, generator, selected, objectives, key, resamples)
        for (robot, generator), selected in groups.items()
    ]


def _label(
    name: str, ours: Callable[[str], bool], information: Mapping[str, str] | None = None
) -> str:
    text = with_information(name, information)
    return f"**{text}** (ours)" if ours(name) else text


def with_information(name: str, information: Mapping[str, str] | None) -> str:
    """``name (class)`` when ``information`` (row name → information class) labels it."""
    label = (information or {}).get(name)
    return f"{name} ({label})" if label else name


def _nobody(name: str) -> bool:
    return False


def summary_table(
    fronts: Sequence[GroupFront],
    ours: Callable[[str], bool] = _nobody,
    information: Mapping[str, str] | None = None,
) -> Table:
    """Per group the front, where *ours* sits, and who meets the criterion.

    ``information`` (row name → information class, see ``Rows.information_labels``) labels
    every row name it holds: ``preview (preview 1 s)``.
    """
    headers = ["robot", "group", "tasks", "Pareto front of medians", "ours"]
    headers += ["meets the criterion (Holm: all pairs / best others)"]
    cells: list[list[str]] = []
    for g in fronts:
        mine = [r for r in g.rows if ours(r.name)]
        where = "; ".join(
            f"{with_information(r.name, information)}: "
            + (
                "on the front"
                if r.on_front
                else ("dominated by " + ", ".join(r.dominated_by) if r.dominated_by else "–")
            )
            + f", {r.verdict()}"
            for r in mine
        )
        meeting = " / ".join(
            ", ".join(with_information(n, information) for n in g.meeting(f)) or "none"
            for f in FAMILIES
        )
        front = ", ".join(_label(n, ours, information) for n in g.front)
        best = with_information(g.best_on_all, information) if g.best_on_all else "none"
        cells.append([g.robot, g.group, str(g.tasks), front, where or "–", meeting, best])
    return Table([*headers, "best median on all objectives"], cells)


def detail_table(front: GroupFront, ours: Callable[[str], bool] = _nobody) -> Table:
    """Every row's medians, front status and its paired tests against the best."""
    headers = ["row", *(f"median {metric(m).heading}" for m in front.objectives), "front"]
    headers += [f"vs best on {metric(m).label}: row, Holm p, outcome" for m in front.objectives]
    rows: list[list[str]] = []
    for r in front.rows:
        place = (
            "**front**"
            if r.on_front
            else ("by " + ", ".join(r.dominated_by) if r.dominated_by else "–")
        )
        cells = [
            f"{c.other} ({_fmt(_other_median(front, c))}), {_p(c.p_holm['all'])}, {c.outcome()}"
            for c in r.comparisons
        ]
        cells += ["–"] * (len(front.objectives) - len(cells))
        rows.append([_label(r.name, ours), *(_fmt(v) for v in r.medians), place, *cells])
        rows[-1].append(f"{r.verdict('all')} / {r.verdict('best')}")
    return Table([*headers, "verdict (all pairs / best others)"], rows)


def _other_median(front: GroupFront, comparison: Comparison) -> float:
    other = front.row(comparison.other)
    k = front.objectives.index(comparison.objective)
    return other.medians[k] if other is not None else math.nan


def counts_sentence(fronts: Sequence[GroupFront], ours: Callable[[str], bool] = _nobody) -> str:
    """One sentence: how many groups a row meets the criterion in, and where *ours* sits."""
    n = len(fronts)
    any_meets = [sum(1 for g in fronts if g.meeting(f)) for f in FAMILIES]
    best_all = sum(1 for g in fronts if g.best_on_all)
    text = (
        f"In {any_meets[0]} of {n} groups some row meets the criterion with Holm over all its "
        f"pairs ({any_meets[1]} with Holm over its tests against the best others only); "
        f"in {best_all} of {n} one row has the best median on every objective."
    )
    names = list(dict.fromkeys(r.name for g in fronts for r in g.rows if ours(r.name)))
    for name in names:
        mine = [r for g in fronts if (r := g.row(name)) is not None]
        text += (
            f" {name}: on the front in {sum(r.on_front for r in mine)} of {len(mine)}, "
            f"meets the criterion in {sum(r.meets() for r in mine)} "
            f"({sum(r.meets('best') for r in mine)} with the smaller family), loses "
            f"significantly in {sum(r.verdict().startswith('loses') for r in mine)}."
        )
    return text
