"""``summary.csv`` (one row per run, a named column per metric) and ``summary.md``."""

from __future__ import annotations

import csv
import enum
from collections.abc import Sequence
from pathlib import Path

from otmm_qp.metrics.metrics import METRIC_NAMES, Metrics
from otmm_qp.metrics.table import columns
from otmm_qp.output.markdown import Table, table_markdown
from otmm_qp.paths import atomic_open, atomic_write_text

ID_COLUMNS = ("experiment", "loop_mode", "controller", "filters", "backend")


class RunOutcome(str, enum.Enum):
    """How a summary row's run ended: the ``outcome`` column (never parsed from a message)."""

    COMPLETED = "completed"  #: ran every step
    STOPPED = "stopped"  #: stopped early; ``error_message`` says why
    SKIPPED = "skipped"  #: never ran (an optional peer library is missing); the message says why

    def __str__(self) -> str:
        return str(self.value)


#: Columns shown in the Markdown table (the CSV has all of them), from the metric table.
MARKDOWN_COLUMNS = columns(
    "max_error",
    "rms_error",
    "max_error_window",
    "max_joint_speed",
    "initial_jump",
    "chattering",
    "max_jump",
    "min_sigma",
    "steps_below_sigma_s",
    "position_violations",
    "blow_up",
    "step_time_median_us",
)


def summary_row(
    identity: dict[str, str],
    metrics: Metrics,
    error_message: str | None,
    outcome: RunOutcome | None = None,
) -> dict[str, object]:
    """One CSV row: identity columns, every metric, the outcome, then the message (or empty).

    ``outcome`` defaults to ``stopped`` when there is a message, else ``completed``.
    """
    row: dict[str, object] = dict(identity)
    for name in METRIC_NAMES:
        row[name] = metrics.get(name, "")
    if outcome is None:
        outcome = RunOutcome.STOPPED if error_message else RunOutcome.COMPLETED
    row["outcome"] = outcome
    row["error_message"] = error_message or ""
    return row


def write_summary_csv(rows: Sequence[dict[str, object]], path: Path) -> None:
    """Write ``summary.csv`` with a stable column order."""
    columns = [*ID_COLUMNS, *METRIC_NAMES, "outcome", "error_message"]
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns)
        writer.writeheader()
        for row in rows:
            writer.writerow({c: _csv_value(row.get(c, "")) for c in columns})


def _csv_value(value: object) -> object:
    if isinstance(value, enum.Enum):
        return str(value)
    if isinstance(value, float):
        return f"{value:.9g}"
    return value


def _format(value: object, spec: str) -> str:
    if isinstance(value, bool):
        return "**yes**" if value else "no"
    if isinstance(value, int | float) and spec:
        try:
            return format(value, spec)
        except (TypeError, ValueError):
            return str(value)
    return str(value)


def write_summary_markdown(rows: Sequence[dict[str, object]], path: Path, title: str) -> None:
    """Write ``summary.md``: one table per experiment and loop mode."""
    lines = [f"# {title}: summary", ""]
    lines.append(
        "Metric definitions: `otmm_qp/metrics/metrics.py`. All columns are in `summary.csv`."
    )
    groups: dict[tuple[str, str], list[dict[str, object]]] = {}
    for row in rows:
        groups.setdefault((str(row["experiment"]), str(row["loop_mode"])), []).append(row)
    for (experiment, mode), group in groups.items():
        lines += ["", f"## {experiment} — {mode}", ""]
        header = ["controller", *(label for _, label, _ in MARKDOWN_COLUMNS)]
        body: list[list[str]] = []
        for row in group:
            cells = [str(row["controller"])]
            cells += [_format(row.get(key, ""), spec) for key, _, spec in MARKDOWN_COLUMNS]
            if row.get("error_message"):
                cells[0] += f" ({row.get('outcome', RunOutcome.STOPPED)}: {row['error_message']})"
            body.append(cells)
        lines += table_markdown(Table(header, body))
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, "\n".join(lines) + "\n")
