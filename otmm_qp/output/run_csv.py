"""The run time-series CSV: its columns, its writer and its streaming reader.

One row per control step, one named column per value (see :func:`write_run_csv`); a file is
a run time series when it has the columns ``t``, ``sigma_min`` and ``q_*``
(:func:`is_run_header`). Where the files go is :class:`~otmm_qp.output.results.ResultsDir`'s.
"""

from __future__ import annotations

import csv
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from otmm_qp.exceptions import ConfigError
from otmm_qp.paths import atomic_open
from otmm_qp.simulation.run_result import RunResult

__all__ = [
    "MAX_RUN_ROWS",
    "RUN_CSV_COLUMNS",
    "RunTable",
    "is_run_header",
    "read_run_table",
    "thinned_rows",
    "write_run_csv",
]

#: Columns a run time series always has (besides its ``q_<joint>`` columns).
RUN_CSV_COLUMNS = ("t", "sigma_min")
#: Default cap on the rows kept of one run time series (see :func:`read_run_table`).
MAX_RUN_ROWS = 20_000


def write_run_csv(result: RunResult, path: Path) -> None:
    """Write a run's time series atomically as CSV: one row per step, one named column per value.

    Columns: ``t``, ``q_<joint>``, ``qdot_<joint>``, ``x, y[, z]`` and their ``_desired``,
    ``error_<i>``, ``sigma_min``, ``p``, ``filter_active``, ``removed``, ``damping``,
    ``scale``, ``weak_speed``, ``status``, ``step_time_us``; with a non-ideal plant or
    conditioning also ``qdot_actual_<joint>``, ``torque_ratio``, ``saturated``,
    ``conditioned``.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    d = result.position.shape[1]
    axes = "xyz"[:d]
    header = ["t"]
    header += [f"q_{name}" for name in result.joint_names]
    header += [f"qdot_{name}" for name in result.joint_names]
    header += [f"{a}" for a in axes] + [f"{a}_desired" for a in axes]
    header += [f"error_{i}" for i in range(result.error.shape[1])]
    header += ["sigma_min", "p", "filter_active", "removed", "damping", "scale", "weak_speed"]
    header += ["status", "step_time_us"]
    plant_columns = result.plant_columns
    if plant_columns:
        header += [f"qdot_actual_{name}" for name in result.joint_names]
        header += ["torque_ratio", "saturated", "conditioned"]
    with atomic_open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        for k in range(result.steps):
            row: list[object] = [f"{result.t[k]:.6f}"]
            row += [f"{v:.9g}" for v in result.q[k]]
            row += [f"{v:.9g}" for v in result.qdot[k]]
            row += [f"{v:.9g}" for v in result.position[k]]
            row += [f"{v:.9g}" for v in result.position_desired[k]]
            row += [f"{v:.9g}" for v in result.error[k]]
            row += [
                f"{result.sigma_min[k]:.9g}",
                f"{result.p[k]:.6g}",
                int(bool(result.filter_active[k])),
                f"{result.removed[k]:.6g}",
                f"{result.damping[k]:.6g}",
                f"{result.scale[k]:.6g}",
                f"{result.weak_speed[k]:.6g}",
                result.status[k],
                f"{result.step_time[k] * 1e6:.2f}",
            ]
            if plant_columns:
                row += [f"{v:.9g}" for v in result.actual_qdot[k]]
                ratio = result.torque_ratio[k] if result.torque_ratio is not None else np.nan
                row += [
                    f"{ratio:.6g}",
                    int(bool(result.saturated is not None and result.saturated[k])),
                    int(bool(result.conditioned is not None and result.conditioned[k])),
                ]
            writer.writerow(row)


def is_run_header(header: Sequence[str]) -> bool:
    """Whether a CSV header is a run time series': ``t``, ``sigma_min`` and ``q_*`` columns."""
    return all(c in header for c in RUN_CSV_COLUMNS) and any(c.startswith("q_") for c in header)


def thinned_rows(reader: Iterator[list[str]], width: int, limit: int) -> list[list[str]]:
    """Complete rows of ``reader`` (``width`` cells), thinned to at most ``limit``, in order.

    Every ``stride``-th row is kept; when ``limit`` is passed, every other kept row is dropped
    and ``stride`` doubles, so memory stays at most ``limit + 1`` rows in one pass. The last
    row is always kept.
    """
    kept: list[list[str]] = []
    stride, index, last = 1, 0, None
    for row in reader:
        if len(row) != width:
            continue
        if index % stride == 0:
            kept.append(row)
            if len(kept) > limit:
                kept = kept[::2]
                stride *= 2
            last = None
        else:
            last = row
        index += 1
    if last is not None:
        kept.append(last)
    return kept


@dataclass(frozen=True)
class RunTable:
    """The text cells of one run time series, as stored.

    Attributes:
        path: The CSV file.
        header: Its column names, length ``C``.
        rows: Its complete rows (``C`` cells each), thinned evenly to the row cap, in order.
    """

    path: Path
    header: tuple[str, ...]
    rows: list[list[str]]


def read_run_table(path: Path, max_rows: int = MAX_RUN_ROWS) -> RunTable:
    """Read a run time series in one streaming pass, keeping at most ``max_rows + 1`` rows.

    Raises:
        ConfigError: Unreadable, not UTF-8, not a CSV, or without the columns ``t``,
            ``q_*``, ``sigma_min``.
    """
    try:
        with path.open(newline="", encoding="utf-8") as handle:
            reader = csv.reader(handle)
            header = next(reader, [])
            if not is_run_header(header):
                raise ConfigError(
                    str(path), "not a run time series (needs columns t, q_*, sigma_min)"
                )
            rows = thinned_rows(reader, len(header), max_rows)
    except (OSError, UnicodeDecodeError, csv.Error) as error:
        raise ConfigError(str(path), f"cannot read the time series: {error}") from None
    return RunTable(path, tuple(header), rows)
