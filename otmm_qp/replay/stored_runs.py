"""Read the stored time series of a results folder back (a replay never re-simulates).

Layout written by ``otmm-qp run`` (see ``otmm_qp/runner/run.py``)::

    RESULTS_DIR/summary.csv                               one row per run (display names)
    RESULTS_DIR/<experiment>/<loop_mode>/<controller>.csv one row per control step

A time-series CSV is recognised by its header (``t``, ``q_*``, ``sigma_min``), so the
folder names may be any safe form of the display names; ``summary.csv`` gives the
display names back when a folder or file name matches one of its rows.
"""

from __future__ import annotations

import csv
import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from otmm_qp.exceptions import ConfigError
from otmm_qp.output.paths import safe_name
from otmm_qp.robots.robot import FloatArray

#: Folders under a results directory that never hold run time series.
_SKIPPED_FOLDERS = frozenset({"replays", "figures"})
_REQUIRED_COLUMNS = ("t", "sigma_min")


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
MAX_ROWS = 20_000
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


def _thinned_rows(reader: Iterator[list[str]], width: int, limit: int) -> list[list[str]]:
    """Complete rows of ``reader`` (``width`` cells), thinned to at most ``limit``, in order.

    Every ``stride``-th row is kept; when ``limit`` is passed, every other kept row is dropped
    and ``stride`` doubles, so memory stays bounded in one pass. The last row is always kept.
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


def _finite_time(text: str) -> bool:
    try:
        return abs(float(text)) <= MAX_MAGNITUDE
    except ValueError:
        return False


def _is_time_series(header: Sequence[str]) -> bool:
    return all(c in header for c in _REQUIRED_COLUMNS) and any(c.startswith("q_") for c in header)


def read_run(path: Path, experiment: str, loop_mode: str, controller: str) -> StoredRun:
    """Read one time-series CSV.

    Raises:
        ConfigError: The file is unreadable, has no rows, or lacks the columns
            ``t``, ``q_*``, ``sigma_min`` and the end-effector position ``x, y[, z]``.
    """
    try:
        with path.open(newline="") as handle:
            reader = csv.reader(handle)
            header = next(reader, [])
            if not _is_time_series(header):
                raise ConfigError(
                    str(path), "not a run time series (needs columns t, q_*, sigma_min)"
                )
            rows = _thinned_rows(reader, len(header), MAX_ROWS)
    except (OSError, UnicodeDecodeError, csv.Error) as error:
        raise ConfigError(str(path), f"cannot read the time series: {error}") from None
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


def _summary_names(results_dir: Path) -> list[tuple[str, str, str]]:
    """``(experiment, loop_mode, controller)`` of every ``summary.csv`` row, in order."""
    path = results_dir / "summary.csv"
    if not path.is_file():
        return []
    try:
        with path.open(newline="") as handle:
            return [
                (row["experiment"], row["loop_mode"], row["controller"])
                for row in csv.DictReader(handle)
                if row.get("experiment") and row.get("loop_mode") and row.get("controller")
            ]
    except (OSError, KeyError, csv.Error, UnicodeDecodeError):
        return []


def _file_forms(name: str) -> set[str]:
    """File-name forms a display name may have been written under."""
    forms = {name, "".join(c if c.isalnum() or c in "-_." else "_" for c in name)}
    forms.add(re.sub(r"[^A-Za-z0-9._-]", "_", name).lstrip(".-"))
    forms.add(safe_name(name))
    return forms


def _display_name(stored: str, candidates: Sequence[str]) -> str:
    for candidate in candidates:
        if stored in _file_forms(candidate):
            return candidate
    return stored


def discover_runs(results_dir: Path) -> list[StoredRun]:
    """Every run time series under ``results_dir``, in ``summary.csv`` order where known.

    Raises:
        ConfigError: ``results_dir`` is not a folder, or holds no run time series.
    """
    if not results_dir.is_dir():
        raise ConfigError("RESULTS_DIR", f"{results_dir} is not a folder")
    names = _summary_names(results_dir)
    runs: list[StoredRun] = []
    for path in sorted(results_dir.glob("*/*/*.csv")):
        relative = path.relative_to(results_dir)
        if relative.parts[0] in _SKIPPED_FOLDERS or path.is_symlink():
            continue
        try:
            with path.open(newline="") as handle:
                header = next(csv.reader(handle), [])
        except (OSError, UnicodeDecodeError, csv.Error):
            continue
        if not _is_time_series(header):
            continue
        experiment = _display_name(relative.parts[0], [n[0] for n in names])
        loop_mode = _display_name(relative.parts[1], [n[1] for n in names])
        controllers = [n[2] for n in names if n[0] == experiment and n[1] == loop_mode]
        controller = _display_name(path.stem, controllers)
        runs.append(read_run(path, experiment, loop_mode, controller))
    if not runs:
        raise ConfigError(
            "RESULTS_DIR",
            f"{results_dir} holds no run time series (<experiment>/<loop_mode>/<controller>.csv);"
            " run an experiment into it first (otmm-qp run CONFIG --out DIR)",
        )
    order = {name: i for i, name in enumerate(names)}
    runs.sort(key=lambda r: order.get((r.experiment, r.loop_mode, r.controller), len(order)))
    return runs


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
