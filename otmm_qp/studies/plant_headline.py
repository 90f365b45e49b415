r"""Which strategies keep their ranking under a realistic plant: the headline of a plants study.

From the episode rows of a study with a ``plants`` axis (controllers named
``controller@plant``), per plant and base controller:

* success rate [%] and the rank by success rate (ties broken by the median max error);
* median max position error [m], median peak commanded joint speed [rad/s], median peak
  commanded jerk [rad/s³] (``max_command_jerk``), the episodes the arm's interface would abort
  (``interface_abort``: a commanded acceleration or jerk past the thresholds the plant declares,
  :mod:`otmm_qp.plants.interface`), median ``filter_switches`` (mean) and, for the MuJoCo plant,
  the median ``peak_torque_ratio`` and the share of episodes with a saturated torque;
* against the ideal plant on the same tasks: the paired Wilcoxon signed-rank test of the max
  error (Holm-corrected over every controller × plant pair) and the Spearman correlation
  :math:`\rho` of the plant's ranking with the ideal ranking.

When the study has both ``qp`` and ``qp-box`` (``qp`` with today's position box), a second
table pairs them per plant on the same tasks (:func:`limit_cost`): episodes with a position-limit
violation, success rates with the exact McNemar test, and the paired Wilcoxon test of the max
error, both Holm-corrected over the plants. ``--pair NEW OLD`` (rows ``controller@plant``)
adds the same comparison for any two rows of the study (:func:`pair_cost`), with the episodes
the arm's interface would abort.

Run as ``otmm-qp study plants RESULTS_DIR`` (prints Markdown).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Hashable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from scipy import stats

from otmm_qp.exceptions import ConfigError
from otmm_qp.output.markdown import Table, table_markdown
from otmm_qp.studies.criteria import INTERFACE_COLUMNS
from otmm_qp.studies.oracle import REFERENCE_NAME
from otmm_qp.studies.rows import read
from otmm_qp.studies.statistics import (
    PairedRates,
    PairedResult,
    holm,
    mcnemar_exact,
    paired_test,
)

__all__ = ["PairedRows", "headline", "limit_cost", "pair_cost", "pair_rows", "plant_rows"]

COLUMNS = [
    "controller", "plant", "robot", "generator", "task_index", "success", "max_error",
    "max_joint_speed", "filter_switches", "peak_torque_ratio", "saturated_steps",
    "position_violations", "max_command_jerk", "command_acceleration_violations",
    "command_jerk_violations",
]  # fmt: skip


def _median(values: list[float]) -> float:
    finite = [v for v in values if v is not None and math.isfinite(v)]
    return float(np.median(finite)) if finite else math.nan


def _aborted(row: dict[str, Any]) -> bool:
    """Whether the arm's interface would have aborted the episode (a threshold passed)."""
    return any(int(row.get(name) or 0) > 0 for name in INTERFACE_COLUMNS)


def _ranks(rate: dict[str, float], error: dict[str, float]) -> dict[str, int]:
    order = sorted(rate, key=lambda c: (-rate[c], error[c] if math.isfinite(error[c]) else 1e300))
    return {c: i + 1 for i, c in enumerate(order)}


def headline(rows: list[dict[str, Any]], reference: str = "ideal") -> str:
    """Markdown table and verdict lines of a plants study's episode rows (see the module).

    Raises:
        ConfigError: ``--reference``: no such plant in the rows.
    """
    rows = [
        r for r in rows if r["controller"] != REFERENCE_NAME
    ]  # the offline reference: not a plant run
    plants = list(dict.fromkeys(str(r["plant"]) for r in rows))
    if reference not in plants:
        raise ConfigError(
            "--reference", f"no plant {reference!r:.40} in the study; have: {', '.join(plants)}"
        )
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for row in rows:
        base = str(row["controller"]).rsplit("@", 1)[0]
        groups.setdefault((str(row["plant"]), base), []).append(row)
    plants = list(dict.fromkeys(str(r["plant"]) for r in rows))
    controllers = list(dict.fromkeys(base for _, base in groups))
    rate = {k: 100.0 * float(np.mean([bool(r["success"]) for r in v])) for k, v in groups.items()}
    error = {k: _median([r["max_error"] for r in v]) for k, v in groups.items()}
    ranks = {
        p: _ranks({c: rate[p, c] for c in controllers}, {c: error[p, c] for c in controllers})
        for p in plants
    }
    tests = []
    for p in plants:
        if p == reference:
            continue
        for c in controllers:
            key = lambda r: (r["robot"], r["generator"], r["task_index"])  # noqa: E731
            ref = {key(r): r["max_error"] for r in groups[reference, c]}
            pairs = [(r["max_error"], ref[key(r)]) for r in groups[p, c] if key(r) in ref]
            a, b = (np.array(x, dtype=float) for x in zip(*pairs, strict=True))
            tests.append(((p, c), paired_test(p, reference, a, b)))
    adjusted = dict(zip([k for k, _ in tests], holm([t.p_value for _, t in tests]), strict=True))
    headers = ["plant", "controller", "rank", "success %", "median max error [m]"]
    headers += [f"Δ error vs {reference}: tasks where {reference} is lower / tied / higher, Holm p"]
    headers += ["median peak speed [rad/s]", "median peak jerk [rad/s³]", "interface aborts"]
    headers += ["mean filter switches", "median peak τ/τ_max", "saturated episodes %"]
    cells: list[list[str]] = []
    for p in plants:
        for c in controllers:
            group = groups[p, c]
            test = dict(tests).get((p, c))
            versus = "—"
            if test is not None:
                versus = f"{test.higher} / {test.ties} / {test.lower}, {adjusted[p, c]:.2g}"
            ratio = _median([r["peak_torque_ratio"] for r in group])
            saturated = 100.0 * float(np.mean([(r["saturated_steps"] or 0) > 0 for r in group]))
            cells.append(
                [p, c, str(ranks[p][c]), f"{rate[p, c]:.0f}", f"{error[p, c]:.3g}", versus]
            )
            cells[-1] += [
                f"{_median([r['max_joint_speed'] for r in group]):.3g}",
                f"{_median([r.get('max_command_jerk', math.nan) for r in group]):.3g}",
                str(sum(1 for r in group if _aborted(r))),
                f"{float(np.mean([r['filter_switches'] or 0 for r in group])):.2f}",
                "—" if math.isnan(ratio) else f"{ratio:.2f}",
                "—" if math.isnan(ratio) else f"{saturated:.0f}",
            ]
    lines = table_markdown(Table(headers, cells, "llrrrlrrrrrr"))
    lines.append("")
    for p in plants:
        if p == reference:
            continue
        order = [ranks[reference][c] for c in controllers]
        here = [ranks[p][c] for c in controllers]
        rho = float(stats.spearmanr(order, here).statistic) if len(controllers) > 2 else math.nan
        moved = [
            f"{c} {ranks[reference][c]}→{ranks[p][c]} ({rate[reference, c]:.0f}→{rate[p, c]:.0f} %)"
            for c in controllers
            if abs(ranks[p][c] - ranks[reference][c]) >= 2 or rate[reference, c] - rate[p, c] >= 15
        ]
        lines.append(
            f"- **{p}**: Spearman ρ = {rho:.2f} with the {reference} ranking; "
            + ("moved ≥ 2 places or lost ≥ 15 points: " + ", ".join(moved) if moved else "no "
               "controller moved ≥ 2 places or lost ≥ 15 points of success")
        )  # fmt: skip
    return "\n".join(lines) + "\n"


def plant_rows(out: Path) -> list[dict[str, Any]]:
    """The judged rows (:func:`otmm_qp.studies.rows.read`) of a study with a plants axis.

    Parts left out (another study's, second copies...) are said on stderr, one line each.

    Raises:
        OtmmError: Not a study folder, or a study without a plants axis.
    """
    frame = read(out)
    for line in frame.notes():
        print(f"otmm-qp: {line}", file=sys.stderr)
    rows = frame.table.select([c for c in COLUMNS if c in frame.table.column_names]).to_pylist()
    if not any(r.get("plant") for r in rows if r["controller"] != REFERENCE_NAME):
        raise ConfigError(str(out), "not a plants study (no episode rows with a plant)")
    return rows


#: A row's task: the same (robot, generator, index) under every controller and plant.
TaskKey = tuple[Any, Any, Any]
#: The label of a row compared by :func:`pair_rows` (a name, or a (plant, controller) pair).
Label = TypeVar("Label", bound=Hashable)


def _task(row: dict[str, Any]) -> TaskKey:
    return (row["robot"], row["generator"], row["task_index"])


@dataclass(frozen=True)
class PairedRows:
    """Two rows of a study compared on the tasks both ran (:func:`pair_rows`).

    Attributes:
        new: The first row's printed name.
        old: The second row's printed name.
        tasks: Number of tasks both ran (the sorted intersection of their tasks).
        aborts: Episodes the arm's interface would abort, (new, old), on those tasks.
        past_limit: Episodes with a position-limit violation, (new, old), on those tasks.
        success: Success rates [%], (new, old), on those tasks.
        rates: The exact McNemar test of success (new = A).
        errors: The paired Wilcoxon test of the max error [m] (new = A).
        p_rates: Holm-adjusted p of ``rates`` over the pairs compared together.
        p_errors: Holm-adjusted p of ``errors`` over the pairs compared together.
    """

    new: str
    old: str
    tasks: int
    aborts: tuple[int, int]
    past_limit: tuple[int, int]
    success: tuple[float, float]
    rates: PairedRates
    errors: PairedResult
    p_rates: float
    p_errors: float


def pair_rows(
    by: Mapping[Label, Mapping[TaskKey, dict[str, Any]]],
    pairs: Sequence[tuple[Label, Label]],
    names: Sequence[tuple[str, str]],
) -> list[PairedRows]:
    """Each ``(new, old)`` pair of ``by``'s rows on the same tasks, Holm over the pairs.

    The one pairing of the plants headline: the tasks are the sorted intersection of the two
    rows' tasks; every count, rate and test is taken on them.

    Args:
        by: Row label → task → episode row.
        pairs: The ``(new, old)`` labels compared.
        names: The printed ``(new, old)`` names of each pair.
    """
    found = [_pair(by[new], by[old], *name) for (new, old), name in zip(pairs, names, strict=True)]
    p_rates = holm([f.rates.p_value for f in found])
    p_errors = holm([f.errors.p_value for f in found])
    return [
        replace(f, p_rates=rate, p_errors=error)
        for f, rate, error in zip(found, p_rates, p_errors, strict=True)
    ]


def _pair(
    new_rows: Mapping[TaskKey, dict[str, Any]],
    old_rows: Mapping[TaskKey, dict[str, Any]],
    new: str,
    old: str,
) -> PairedRows:
    """One pair on the sorted intersection of its tasks (Holm p: not yet adjusted, NaN)."""
    tasks = sorted(set(new_rows) & set(old_rows), key=str)
    a, b = [new_rows[t] for t in tasks], [old_rows[t] for t in tasks]
    success = [np.array([bool(r["success"]) for r in x], dtype=bool) for x in (a, b)]
    maxima = [np.array([r["max_error"] for r in x], dtype=float) for x in (a, b)]
    aborts = [sum(_aborted(r) for r in x) for x in (a, b)]
    past = [sum((r["position_violations"] or 0) > 0 for r in x) for x in (a, b)]
    return PairedRows(
        new,
        old,
        len(tasks),
        (aborts[0], aborts[1]),
        (past[0], past[1]),
        (100.0 * float(np.mean(success[0])), 100.0 * float(np.mean(success[1]))),
        mcnemar_exact(new, old, success[0], success[1]),
        paired_test(new, old, maxima[0], maxima[1]),
        math.nan,
        math.nan,
    )


def _mcnemar_cell(pair: PairedRows) -> str:
    return f"{pair.rates.a_only} / {pair.rates.b_only}, {pair.p_rates:.2g}"


def _error_cell(pair: PairedRows) -> str:
    t = pair.errors
    return f"{t.lower} / {t.ties} / {t.higher}, {pair.p_errors:.2g}"


def limit_cost(rows: list[dict[str, Any]], new: str = "qp", old: str = "qp-box") -> str:
    """Markdown: ``new`` against ``old`` per plant on the same tasks (see the module)."""
    by: dict[tuple[str, str], dict[TaskKey, dict[str, Any]]] = {}
    for row in rows:
        base = str(row["controller"]).rsplit("@", 1)[0]
        if base in (new, old):
            by.setdefault((str(row["plant"]), base), {})[_task(row)] = row
    plants = [p for p in dict.fromkeys(p for p, _ in by) if (p, new) in by and (p, old) in by]
    if not plants:
        return ""
    pairs = pair_rows(by, [((p, new), (p, old)) for p in plants], [(new, old)] * len(plants))
    headers = ["plant", f"episodes with a position-limit violation: {new} / {old}"]
    headers += [f"success %: {new} / {old}", f"tasks only {new} / only {old} succeeds, Holm p"]
    headers += [f"max error: tasks {new} lower / tied / higher, Holm p"]
    cells = [
        [p, f"{pair.past_limit[0]} / {pair.past_limit[1]}"]
        + [f"{pair.success[0]:.0f} / {pair.success[1]:.0f}", _mcnemar_cell(pair)]
        + [_error_cell(pair)]
        for p, pair in zip(plants, pairs, strict=True)
    ]
    return "\n".join(table_markdown(Table(headers, cells, "lrrll"))) + "\n"


def pair_cost(rows: list[dict[str, Any]], pairs: list[tuple[str, str]]) -> str:
    """Markdown: each ``(new, old)`` pair of rows (``controller@plant``) on the same tasks.

    Per pair: episodes the arm's interface would abort and episodes past a position limit
    (new / old), success rates with the exact McNemar test and the paired Wilcoxon test of the
    max error, both Holm-corrected over the pairs. ``new`` and ``old`` may run under different
    plants (e.g. ``qp-cmd@franka_fci_raw`` against ``qp@franka_fci``).

    Raises:
        ConfigError: A named row that the study does not hold.
    """
    by: dict[str, dict[TaskKey, dict[str, Any]]] = {}
    for row in rows:
        by.setdefault(str(row["controller"]), {})[_task(row)] = row
    for name in (name for pair in pairs for name in pair):
        if name not in by:
            raise ConfigError("--pair", f"no rows {name!r:.60}; have: {', '.join(sorted(by))}")
    headers = ["new / old", "tasks", "interface aborts", "past a position limit", "success %"]
    headers += ["tasks only new / only old succeeds, Holm p"]
    headers += ["max error: tasks new lower / tied / higher, Holm p"]
    cells = [
        [f"{pair.new} / {pair.old}", str(pair.tasks)]
        + [f"{pair.aborts[0]} / {pair.aborts[1]}", f"{pair.past_limit[0]} / {pair.past_limit[1]}"]
        + [f"{pair.success[0]:.0f} / {pair.success[1]:.0f}", _mcnemar_cell(pair)]
        + [_error_cell(pair)]
        for pair in pair_rows(by, pairs, pairs)
    ]
    return "\n".join(table_markdown(Table(headers, cells, "lrrrrll"))) + "\n"
