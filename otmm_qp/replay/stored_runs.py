"""The stored time series of a results folder as arrays (a replay never re-simulates).

The folder's layout and the CSV format are :class:`~otmm_qp.output.results.ResultsDir`'s:
it finds the runs (``<experiment>/<loop_mode>/<controller>.csv``, recognised by their
header ``t``, ``q_*``, ``sigma_min``, named by ``summary.csv``) and streams each file,
thinned to :data:`MAX_ROWS`. This module turns the text cells into arrays, a value beyond
:data:`MAX_MAGNITUDE` (or text) into NaN.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from otmm_qp.exceptions import ConfigError
from otmm_qp.output.results import ResultsDir, RunFile
from otmm_qp.output.run_csv import MAX_RUN_ROWS, RunTable, read_run_table
from otmm_qp.robots.robot import FloatArray


@dataclass
class StoredRun:
    """The time series of one run, as read from its CSV.

    Attributes:
        experiment: Experiment display name.
        loop_mode: Loop mode (``feedforward``, ``clik``, ``newton``).
        controller: Controller display name.
        path: The CSV file.
        joint_names: Joint names from the ``q_*`` columns, length ``nv``.
        t: Times [s], shape ``(N,)``.
        q: Joint coordinates [rad], shape ``(N, nv)``.
        position: End-effector position [m], shape ``(N, d)``, d = 2 (planar) or 3.
        position_desired: Desired position [m], shape ``(N, d)``.
        sigma_min: Smallest singular value of the weighted Jacobian, shape ``(N,)``.
        status: Backend status per step, shape ``(N,)``.
    """

    experiment: str
    loop_mode: str
    controller: str
    path: Path
    joint_names: tuple[str, ...]
    t: FloatArray
    q: FloatArray
    position: FloatArray
    position_desired: FloatArray
    sigma_min: FloatArray
    status: tuple[str, ...]

    @property
    def steps(self) -> int:
        """Number of stored steps ``N``."""
        return int(self.t.size)

    @property
    def dimension(self) -> int:
        """2 for a planar arm, 3 for a spatial one."""
        return int(self.position.shape[1])

    @property
    def scenario(self) -> tuple[str, str]:
        """``(experiment, loop_mode)``: the runs a replay shows together."""
        return (self.experiment, self.loop_mode)


#: Most rows kept of one time series; longer ones are thinned evenly while they are read
#: (a replay shows at most a few hundred frames), so a 10^7-row CSV is never held whole.
MAX_ROWS = MAX_RUN_ROWS
#: Largest magnitude read as a number; beyond it (1e300...) a value is no position, angle or
#: time a run produces and is read as NaN, like text.
MAX_MAGNITUDE = 1.0e9


def _float_column(rows: list[list[str]], index: int) -> FloatArray:
    values = np.empty(len(rows))
    for k, row in enumerate(rows):
        try:
            values[k] = float(row[index])
        except (ValueError, IndexError):
            values[k] = np.nan
    values[~(np.abs(values) <= MAX_MAGNITUDE)] = np.nan
    return values


def _finite_time(text: str) -> bool:
    try:
        return abs(float(text)) <= MAX_MAGNITUDE
    except ValueError:
        return False


def read_run(path: Path, experiment: str, loop_mode: str, controller: str) -> StoredRun:
    """Read one time-series CSV (:func:`~otmm_qp.output.results.read_run_table`).

    Raises:
        ConfigError: The file is unreadable, has no rows, or lacks the columns
            ``t``, ``q_*``, ``sigma_min`` and the end-effector position ``x, y[, z]``.
    """
    return stored_run(read_run_table(path, MAX_ROWS), experiment, loop_mode, controller)


def stored_run(table: RunTable, experiment: str, loop_mode: str, controller: str) -> StoredRun:
    """The arrays of one run time series' text cells.

    Raises:
        ConfigError: No complete row with a finite time, or no end-effector position columns.
    """
    path, header, rows = table.path, list(table.header), table.rows
    t_index = header.index("t")
    rows = [row for row in rows if _finite_time(row[t_index])]
    if not rows:
        raise ConfigError(str(path), "the time series has no complete row with a finite time")
    column = {name: i for i, name in enumerate(header)}
    joints = tuple(name[2:] for name in header if name.startswith("q_"))
    axes = "xyz" if "z" in column else "xy"
    if not all(a in column and f"{a}_desired" in column for a in axes):
        raise ConfigError(str(path), "the time series has no end-effector position columns")

    def block(names: Sequence[str]) -> FloatArray:
        return np.column_stack([_float_column(rows, column[n]) for n in names])

    status_index = column.get("status")
    return StoredRun(
        experiment=experiment,
        loop_mode=loop_mode,
        controller=controller,
        path=path,
        joint_names=joints,
        t=_float_column(rows, column["t"]),
        q=block([f"q_{j}" for j in joints]),
        position=block(list(axes)),
        position_desired=block([f"{a}_desired" for a in axes]),
        sigma_min=_float_column(rows, column["sigma_min"]),
        status=tuple(row[status_index] if status_index is not None else "" for row in rows),
    )


def discover_runs(results_dir: Path) -> list[StoredRun]:
    """Every run time series under ``results_dir``, in ``summary.csv`` order where known.

    Raises:
        ConfigError: ``results_dir`` is not a folder, or holds no run time series.
    """
    results = ResultsDir(results_dir)
    files = results.run_files()
    if not files:
        raise ConfigError(
            "RESULTS_DIR",
            f"{results_dir} holds no run time series (<experiment>/<loop_mode>/<controller>.csv);"
            " run an experiment into it first (otmm-qp run CONFIG --out DIR)",
        )
    return [_read(results, run) for run in files]


def _read(results: ResultsDir, run: RunFile) -> StoredRun:
    table = results.read_run(run, MAX_ROWS)
    return stored_run(table, run.experiment, run.loop_mode, run.controller)


def select_runs(
    runs: Sequence[StoredRun], experiment: str | None = None, controller: str | None = None
) -> list[StoredRun]:
    """The runs of ``experiment`` and ``controller`` (all when None).

    Names match the display name or its file-name form.

    Raises:
        ConfigError: An unknown name (``--experiment``/``--controller``), listing those available.
    """
    chosen = list(runs)
    if experiment is not None:
        chosen = [
            r for r in chosen if experiment == r.experiment or _matches(experiment, r.path, 3)
        ]
        if not chosen:
            available = sorted({r.experiment for r in runs})
            raise ConfigError(
                "--experiment",
                f"unknown experiment {experiment!r}; available: {', '.join(available)}",
            )
    if controller is not None:
        pool = chosen
        chosen = [r for r in pool if controller == r.controller or _matches(controller, r.path, 1)]
        if not chosen:
            available = sorted({r.controller for r in pool})
            where = f" in experiment {experiment!r}" if experiment is not None else ""
            raise ConfigError(
                "--controller",
                f"unknown controller {controller!r}{where}; available: {', '.join(available)}",
            )
    return chosen


def _matches(name: str, path: Path, level: int) -> bool:
    """Whether ``name`` equals the folder/file name ``level`` steps up from the CSV."""
    part = path.stem if level == 1 else path.parents[level - 2].name
    return name == part


def group_scenarios(runs: Sequence[StoredRun]) -> dict[tuple[str, str], list[StoredRun]]:
    """Runs by ``(experiment, loop_mode)``, in order."""
    groups: dict[tuple[str, str], list[StoredRun]] = {}
    for run in runs:
        groups.setdefault(run.scenario, []).append(run)
    return groups
