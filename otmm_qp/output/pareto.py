r"""Which strategy wins where: Pareto fronts over window error, peak speed and max jump.

A run *dominates* another of the same scenario (experiment, loop mode) when it is no worse
on all three objectives — ``max_error_window`` [m], ``max_joint_speed`` [rad/s] and
``max_jump`` [rad/s] — and strictly better on at least one. Runs that blew up or did not
complete are never on a front. Usage::

    otmm-qp pareto RESULTS_DIR [RESULTS_DIR ...] --out DIR

reads each ``summary.csv`` and writes ``DIR/pareto.md`` (per scenario: the front, the best
run per objective, the runs no other run dominates) and ``DIR/pareto.png``.
"""

from __future__ import annotations

import io
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from otmm_qp.metrics.table import metric
from otmm_qp.output.markdown import Table, table_markdown
from otmm_qp.output.results import IDENTITY_COLUMNS, ResultsDir
from otmm_qp.output.summary import RunOutcome
from otmm_qp.paths import atomic_write_bytes, atomic_write_text

#: The objectives, all minimised (rows of the metric table with ``lower_is_better``).
OBJECTIVES: tuple[str, ...] = tuple(
    m.name
    for m in map(metric, ("max_error_window", "max_joint_speed", "max_jump"))
    if m.lower_is_better
)


@dataclass(frozen=True)
class Entry:
    """One run's objectives.

    Attributes:
        scenario: ``experiment/loop_mode``.
        controller: Controller name.
        values: The :data:`OBJECTIVES`, in order.
        valid: Completed and did not blow up.
    """

    scenario: str
    controller: str
    values: tuple[float, ...]
    valid: bool


def dominates(a: Sequence[float], b: Sequence[float]) -> bool:
    """Whether ``a`` is no worse than ``b`` everywhere and better somewhere (minimising)."""
    return all(x <= y for x, y in zip(a, b, strict=True)) and any(
        x < y for x, y in zip(a, b, strict=True)
    )


def pareto_front(entries: Sequence[Entry]) -> list[Entry]:
    """The valid entries no other valid entry dominates (input order kept)."""
    valid = [e for e in entries if e.valid]
    return [e for e in valid if not any(dominates(o.values, e.values) for o in valid)]


def read_summary(path: Path) -> list[Entry]:
    """Entries of one ``summary.csv`` (read by :meth:`ResultsDir.summary_records`).

    Raises:
        OtmmError: The file is missing, unreadable or lacks a needed column.
    """
    records = ResultsDir(path.parent).summary_records((*IDENTITY_COLUMNS, *OBJECTIVES))
    entries = []
    for row in records:
        if row.get("outcome") == RunOutcome.SKIPPED:
            continue
        try:
            values = tuple(float(row[c]) for c in OBJECTIVES)
        except ValueError:
            values = (math.inf,) * len(OBJECTIVES)
        valid = (
            all(math.isfinite(v) for v in values)
            and row.get("blow_up", "False") not in ("True", "true", "1")
            and row.get("completed", "True") not in ("False", "false", "0")
        )
        scenario = f"{row['experiment']}/{row['loop_mode']}"
        entries.append(Entry(scenario, row["controller"], values, valid))
    return entries


def _objective(index: int) -> Callable[[Entry], float]:
    """Sort key: objective ``index`` of an entry."""

    def key(entry: Entry) -> float:
        return entry.values[index]

    return key


def _by_scenario(entries: Sequence[Entry]) -> dict[str, list[Entry]]:
    groups: dict[str, list[Entry]] = {}
    for entry in entries:
        groups.setdefault(entry.scenario, []).append(entry)
    return groups


def pareto_markdown(entries: Sequence[Entry]) -> str:
    """The Markdown table: per scenario the best run per objective and the Pareto front."""
    lines = [
        "# Which strategy wins where",
        "",
        "Objectives (minimised): window error [m], peak joint speed [rad/s], max one-step jump "
        "[rad/s]. A run is on the front when no other run of the scenario is at least as good "
        "on all three and better on one; runs that blew up are excluded.",
        "",
    ]
    cells: list[list[str]] = []
    wins: dict[str, int] = {}
    for scenario, group in _by_scenario(entries).items():
        front = pareto_front(group)
        valid = [e for e in group if e.valid]
        best = []
        for i in range(len(OBJECTIVES)):
            if not valid:
                best.append("—")
                continue
            top = min(valid, key=_objective(i))
            best.append(f"{top.controller} ({top.values[i]:.3g})")
        for entry in front:
            wins[entry.controller] = wins.get(entry.controller, 0) + 1
        names = ", ".join(e.controller for e in front) or "—"
        cells.append([scenario, best[0], best[1], best[2], names])
    headers = ["scenario", "best window error", "best peak speed", "best max jump"]
    lines += table_markdown(Table([*headers, "Pareto front"], cells))
    total = str(len(_by_scenario(entries)))
    ranked = sorted(wins.items(), key=lambda item: (-item[1], item[0]))
    counts = [[name, str(count), total] for name, count in ranked]
    lines += [
        "",
        *table_markdown(Table(["strategy", "on the front in", "of scenarios"], counts, "lrr")),
    ]
    return "\n".join(lines) + "\n"


def pareto_figure(entries: Sequence[Entry]) -> bytes:
    """PNG: peak speed vs window error per scenario, marker area ∝ max jump, front ringed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = _by_scenario(entries)
    count = max(1, len(groups))
    columns = min(4, count)
    rows = math.ceil(count / columns)
    figure, axes = plt.subplots(rows, columns, figsize=(4.2 * columns, 3.6 * rows), squeeze=False)
    for axis in axes.flat[count:]:
        axis.set_visible(False)
    for axis, (scenario, group) in zip(axes.flat, groups.items(), strict=False):
        front = {e.controller for e in pareto_front(group)}
        for entry in (e for e in group if e.valid):
            error, speed, jump = entry.values
            size = 20.0 + 200.0 * min(jump, 2.0) / 2.0
            axis.scatter(
                max(error, 1e-12),
                max(speed, 1e-12),
                s=size,
                edgecolors="k" if entry.controller in front else "none",
                linewidths=1.5,
                alpha=0.7,
            )
            axis.annotate(entry.controller, (max(error, 1e-12), max(speed, 1e-12)), fontsize=6)
        axis.set_xscale("log")
        axis.set_yscale("log")
        axis.set_title(scenario, fontsize=9)
        axis.set_xlabel("window error [m]", fontsize=8)
        axis.set_ylabel("peak joint speed [rad/s]", fontsize=8)
    figure.suptitle("Pareto: marker area ∝ max jump (capped at 2 rad/s); ringed = on the front")
    figure.tight_layout()
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=110)
    plt.close(figure)
    return buffer.getvalue()


def write_pareto(results: Sequence[Path], out_dir: Path) -> tuple[Path, Path]:
    """Read ``summary.csv`` of each results folder; write ``pareto.md`` and ``pareto.png``."""
    entries: list[Entry] = []
    for folder in results:
        entries.extend(read_summary(Path(folder) / "summary.csv"))
    out_dir.mkdir(parents=True, exist_ok=True)
    markdown, png = out_dir / "pareto.md", out_dir / "pareto.png"
    atomic_write_text(markdown, pareto_markdown(entries))
    atomic_write_bytes(png, pareto_figure(entries))
    return markdown, png
