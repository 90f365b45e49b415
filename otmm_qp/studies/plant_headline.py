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
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from otmm_qp.exceptions import ConfigError
from otmm_qp.studies.criteria import INTERFACE_COLUMNS
from otmm_qp.studies.oracle import REFERENCE_NAME
from otmm_qp.studies.rows import read
from otmm_qp.studies.statistics import holm, mcnemar_exact, paired_test

__all__ = ["headline", "limit_cost", "pair_cost", "plant_rows"]

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
    lines = [
        "| plant | controller | rank | success % | median max error [m] | Δ error vs "
        f"{reference}: tasks where {reference} is lower / tied / higher, Holm p | "
        "median peak speed [rad/s] | median peak jerk [rad/s³] | interface aborts | "
        "mean filter switches | median peak τ/τ_max | saturated episodes % |",
        "|---|---|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|",
    ]
    for p in plants:
        for c in controllers:
            group = groups[p, c]
            test = dict(tests).get((p, c))
            versus = "—"
            if test is not None:
                versus = f"{test.higher} / {test.ties} / {test.lower}, {adjusted[p, c]:.2g}"
            ratio = _median([r["peak_torque_ratio"] for r in group])
            saturated = 100.0 * float(np.mean([(r["saturated_steps"] or 0) > 0 for r in group]))
            lines.append(
                f"| {p} | {c} | {ranks[p][c]} | {rate[p, c]:.0f} | {error[p, c]:.3g} | {versus} "
                f"| {_median([r['max_joint_speed'] for r in group]):.3g} "
                f"| {_median([r.get('max_command_jerk', math.nan) for r in group]):.3g} "
                f"| {sum(1 for r in group if _aborted(r))} "
                f"| {float(np.mean([r['filter_switches'] or 0 for r in group])):.2f} "
                f"| {'—' if math.isnan(ratio) else f'{ratio:.2f}'} "
                f"| {'—' if math.isnan(ratio) else f'{saturated:.0f}'} |"
            )
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


def limit_cost(rows: list[dict[str, Any]], new: str = "qp", old: str = "qp-box") -> str:
    """Markdown: ``new`` against ``old`` per plant on the same tasks (see the module)."""
    key = lambda r: (r["robot"], r["generator"], r["task_index"])  # noqa: E731
    by: dict[tuple[str, str], dict[Any, dict[str, Any]]] = {}
    for row in rows:
        base = str(row["controller"]).rsplit("@", 1)[0]
        if base in (new, old):
            by.setdefault((str(row["plant"]), base), {})[key(row)] = row
    plants = [p for p in dict.fromkeys(p for p, _ in by) if (p, new) in by and (p, old) in by]
    if not plants:
        return ""
    rates, errors = [], []
    for p in plants:
        tasks = sorted(set(by[p, new]) & set(by[p, old]), key=str)
        a = [by[p, new][t] for t in tasks]
        b = [by[p, old][t] for t in tasks]
        success = [np.array([bool(r["success"]) for r in x]) for x in (a, b)]
        rates.append(mcnemar_exact(new, old, success[0], success[1]))
        maxima = [np.array([r["max_error"] for r in x], dtype=float) for x in (a, b)]
        errors.append(paired_test(new, old, maxima[0], maxima[1]))
    p_rates = holm([r.p_value for r in rates])
    p_errors = holm([t.p_value for t in errors])
    lines = [
        f"| plant | episodes with a position-limit violation: {new} / {old} | success %: "
        f"{new} / {old} | tasks only {new} / only {old} succeeds, Holm p | max error: tasks "
        f"{new} lower / tied / higher, Holm p |",
        "|---|---:|---:|---|---|",
    ]
    for i, p in enumerate(plants):
        pair = (list(by[p, new].values()), list(by[p, old].values()))
        violations = [sum((r["position_violations"] or 0) > 0 for r in x) for x in pair]
        percent = [100.0 * float(np.mean([bool(r["success"]) for r in x])) for x in pair]
        r, t = rates[i], errors[i]
        lines.append(
            f"| {p} | {violations[0]} / {violations[1]} | {percent[0]:.0f} / {percent[1]:.0f} | "
            f"{r.a_only} / {r.b_only}, {p_rates[i]:.2g} | "
            f"{t.lower} / {t.ties} / {t.higher}, {p_errors[i]:.2g} |"
        )
    return "\n".join(lines) + "\n"


def pair_cost(rows: list[dict[str, Any]], pairs: list[tuple[str, str]]) -> str:
    """Markdown: each ``(new, old)`` pair of rows (``controller@plant``) on the same tasks.

    Per pair: episodes the arm's interface would abort and episodes past a position limit
    (new / old), success rates with the exact McNemar test and the paired Wilcoxon test of the
    max error, both Holm-corrected over the pairs. ``new`` and ``old`` may run under different
    plants (e.g. ``qp-cmd@franka_fci_raw`` against ``qp@franka_fci``).

    Raises:
        ConfigError: A named row that the study does not hold.
    """
    key = lambda r: (r["robot"], r["generator"], r["task_index"])  # noqa: E731
    by: dict[str, dict[Any, dict[str, Any]]] = {}
    for row in rows:
        by.setdefault(str(row["controller"]), {})[key(row)] = row
    for name in (name for pair in pairs for name in pair):
        if name not in by:
            raise ConfigError("--pair", f"no rows {name!r:.60}; have: {', '.join(sorted(by))}")
    rates, errors = [], []
    counts: list[tuple[tuple[int, int, float], tuple[int, int, float], int]] = []
    for new, old in pairs:
        tasks = sorted(set(by[new]) & set(by[old]), key=str)
        a, b = [by[new][t] for t in tasks], [by[old][t] for t in tasks]
        success = [np.array([bool(r["success"]) for r in x]) for x in (a, b)]
        rates.append(mcnemar_exact(new, old, success[0], success[1]))
        maxima = [np.array([r["max_error"] for r in x], dtype=float) for x in (a, b)]
        errors.append(paired_test(new, old, maxima[0], maxima[1]))
        tallies = [
            (
                sum(_aborted(r) for r in x),
                sum((r["position_violations"] or 0) > 0 for r in x),
                100.0 * float(np.mean(success[i])),
            )
            for i, x in enumerate((a, b))
        ]
        counts.append((tallies[0], tallies[1], len(tasks)))
    p_rates = holm([r.p_value for r in rates])
    p_errors = holm([t.p_value for t in errors])
    lines = [
        "| new / old | tasks | interface aborts | past a position limit | success % | tasks "
        "only new / only old succeeds, Holm p | max error: tasks new lower / tied / higher, "
        "Holm p |",
        "|---|---:|---:|---:|---:|---|---|",
    ]
    for i, (new, old) in enumerate(pairs):
        (abort_a, past_a, rate_a), (abort_b, past_b, rate_b), count = counts[i]
        r, t = rates[i], errors[i]
        lines.append(
            f"| {new} / {old} | {count} | {abort_a} / {abort_b} | {past_a} / {past_b} | "
            f"{rate_a:.0f} / {rate_b:.0f} | {r.a_only} / {r.b_only}, {p_rates[i]:.2g} | "
            f"{t.lower} / {t.ties} / {t.higher}, {p_errors[i]:.2g} |"
        )
    return "\n".join(lines) + "\n"
