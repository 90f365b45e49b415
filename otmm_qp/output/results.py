"""The one owner of a run folder's layout: where each file goes and how ``summary.csv`` is read.

::

    <out>/summary.csv, summary.md, report.html, report.md, claims.md
    <out>/<experiment>/<loop mode>/<controller>.csv     one time series per run
    <out>/<experiment>/robot.json                       the config's robot block (replay)
    <out>/replays/, <out>/figures/                      never run time series

Names become path parts only through :func:`~otmm_qp.paths.safe_name` (controller
slugs made unique per experiment), and every path is checked to stay inside the folder.
Writers and readers (runner sink, report, Pareto index, replay) go through
:class:`ResultsDir`; a run CSV (format: :mod:`otmm_qp.output.run_csv`) is read streaming and
thinned to a row cap, so a hostile 10⁷-row file is never held whole.
"""

from __future__ import annotations

import csv
import io
import json
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from otmm_qp.exceptions import ConfigError, OtmmError
from otmm_qp.output.run_csv import (
    MAX_RUN_ROWS,
    RunTable,
    is_run_header,
    read_run_table,
    write_run_csv,
)
from otmm_qp.paths import atomic_write_bytes, ensure_inside, safe_name, unique_names
from otmm_qp.simulation.run_result import RunResult

SUMMARY_CSV = "summary.csv"
SUMMARY_MD = "summary.md"
REPORT_HTML = "report.html"
REPORT_MD = "report.md"
CLAIMS_MD = "claims.md"
#: Columns every ``summary.csv`` row has: which run it is.
IDENTITY_COLUMNS = ("experiment", "loop_mode", "controller")
#: An experiment's robot record: ``{"type": NAME, "params": {...}}``, the config's robot block.
ROBOT_JSON = "robot.json"
#: Largest ``robot.json`` read [bytes].
MAX_ROBOT_JSON_BYTES = 64 * 1024
#: Top-level folders of a run folder that never hold run time series.
NON_RUN_FOLDERS = frozenset({"replays", "figures"})


@dataclass(frozen=True)
class RunFile:
    """One stored run of a run folder.

    Attributes:
        experiment: Experiment display name (from ``summary.csv`` when a row matches).
        loop_mode: Loop mode.
        controller: Controller display name.
        path: Its time series ``<experiment>/<loop mode>/<controller>.csv``.
    """

    experiment: str
    loop_mode: str
    controller: str
    path: Path

    @property
    def experiment_dir(self) -> Path:
        """The experiment's folder (where its ``robot.json`` lives)."""
        return self.path.parent.parent


def _file_forms(name: str) -> set[str]:
    """File-name forms a display name may have been written under (safe names over time)."""
    forms = {name, "".join(c if c.isalnum() or c in "-_." else "_" for c in name)}
    forms.add(re.sub(r"[^A-Za-z0-9._-]", "_", name).lstrip(".-"))
    forms.add(safe_name(name))
    return forms


def _display_name(stored: str, candidates: Sequence[str]) -> str:
    for candidate in candidates:
        if stored in _file_forms(candidate):
            return candidate
    return stored


class ResultsDir:
    """A run folder (``otmm-qp run --out``).

    Args:
        path: The folder.
    """

    def __init__(self, path: Path | str) -> None:
        self.path = Path(path)

    def file(self, name: str) -> Path:
        """A top-level file of the folder (e.g. :data:`SUMMARY_CSV`), checked to stay inside."""
        return ensure_inside(self.path, self.path / name)

    def run_csv(
        self, experiment: str, loop_mode: str, controller: str, names: Sequence[str]
    ) -> Path:
        """``<experiment>/<loop mode>/<controller>.csv`` through the safe, unique names.

        Args:
            experiment: Experiment name.
            loop_mode: Loop mode.
            controller: Controller name.
            names: Controller names of the experiment, in config order (for unique slugs).

        Raises:
            OutputPathError: The path would leave the folder.
        """
        stem = unique_names(list(names))[controller]
        folder = self.path / safe_name(experiment) / safe_name(loop_mode)
        return ensure_inside(self.path, folder / f"{stem}.csv")

    def write_run(self, result: RunResult, controllers: Sequence[str]) -> Path:
        """Write ``result``'s time series to its :meth:`run_csv` path (atomically).

        Args:
            result: One finished run.
            controllers: Controller names of its experiment, in config order (unique slugs).

        Raises:
            OutputPathError: The path would leave the folder.
        """
        path = self.run_csv(result.experiment, result.loop_mode, result.controller, controllers)
        write_run_csv(result, path)
        return path

    def run_names(self) -> list[tuple[str, str, str]]:
        """``(experiment, loop_mode, controller)`` of every ``summary.csv`` row, in order.

        Lenient (a replay needs no summary): ``[]`` when the file is missing or unreadable;
        rows with an empty name are skipped.
        """
        try:
            records = self.summary_records()
        except OtmmError:
            return []
        names = [tuple(r.get(c, "") for c in IDENTITY_COLUMNS) for r in records]
        return [(e, m, c) for e, m, c in names if e and m and c]

    def run_files(self) -> list[RunFile]:
        """Every run time series of the folder, in ``summary.csv`` order where known.

        Files are found by the layout (``<experiment>/<loop mode>/<controller>.csv``, outside
        :data:`NON_RUN_FOLDERS`, not symlinks) and their header (:func:`is_run_header`). A
        file at the :meth:`run_csv` path of a ``summary.csv`` row takes that row's display
        names; other files (a hand-made or older folder) are matched to the summary's names
        by their file-name forms, else keep their folder and file names.

        Raises:
            ConfigError: The folder does not exist.
        """
        if not self.path.is_dir():
            raise ConfigError("RESULTS_DIR", f"{self.path} is not a folder")
        names = self.run_names()
        written = self._summary_paths(names)
        found: list[RunFile] = []
        for path in sorted(self.path.glob("*/*/*.csv")):
            relative = path.relative_to(self.path)
            if relative.parts[0] in NON_RUN_FOLDERS or path.is_symlink():
                continue
            try:
                with path.open(newline="", encoding="utf-8") as handle:
                    header = next(csv.reader(handle), [])
            except (OSError, UnicodeDecodeError, csv.Error):
                continue
            if not is_run_header(header):
                continue
            known = written.get(os.path.realpath(path))
            if known is not None:  # the path run_csv gives this summary row
                found.append(RunFile(*known, path))
                continue
            experiment = _display_name(relative.parts[0], [n[0] for n in names])
            loop_mode = _display_name(relative.parts[1], [n[1] for n in names])
            controllers = [n[2] for n in names if n[0] == experiment and n[1] == loop_mode]
            found.append(
                RunFile(experiment, loop_mode, _display_name(path.stem, controllers), path)
            )
        order = {name: i for i, name in enumerate(names)}
        found.sort(key=lambda r: order.get((r.experiment, r.loop_mode, r.controller), len(order)))
        return found

    def _summary_paths(
        self, names: Sequence[tuple[str, str, str]]
    ) -> dict[str, tuple[str, str, str]]:
        """Resolved :meth:`run_csv` path → ``(experiment, loop_mode, controller)`` per summary row.

        An experiment's controller names are taken in their summary order (the config order,
        in which :meth:`run_csv` made their slugs unique).
        """
        order: dict[str, list[str]] = {}
        for experiment, _, controller in names:
            listed = order.setdefault(experiment, [])
            if controller not in listed:
                listed.append(controller)
        paths: dict[str, tuple[str, str, str]] = {}
        for experiment, loop_mode, controller in names:
            try:
                path = self.run_csv(experiment, loop_mode, controller, order[experiment])
            except OtmmError:
                continue
            paths.setdefault(str(path), (experiment, loop_mode, controller))
        return paths

    def read_run(self, run: RunFile, max_rows: int = MAX_RUN_ROWS) -> RunTable:
        """The time series of ``run`` (see :func:`read_run_table`), checked to stay inside.

        Raises:
            OutputPathError: The file resolves outside the folder.
            ConfigError: Not a readable run time series.
        """
        ensure_inside(self.path, run.path)
        return read_run_table(run.path, max_rows)

    def robot_json(self, experiment_dir: Path) -> Path:
        """``<experiment>/robot.json`` of an experiment folder of this run folder."""
        return experiment_dir / ROBOT_JSON

    def read_robot_record(self, experiment_dir: Path) -> dict[str, Any] | None:
        """The robot block an experiment's ``robot.json`` records, or None when there is none.

        Returns:
            ``{"type": str, "params": dict}`` (``params`` ``{}`` when absent or null).

        Raises:
            ConfigError: A symlink, a file over :data:`MAX_ROBOT_JSON_BYTES`, not a JSON
                object with a string ``type`` and an object ``params`` (without ``type``).
        """
        record = self.robot_json(experiment_dir)
        field = str(record)
        if record.is_symlink():
            raise ConfigError(field, "is a symlink; a robot record must be a plain file")
        if not record.is_file():
            return None
        try:
            if record.stat().st_size > MAX_ROBOT_JSON_BYTES:
                raise ConfigError(
                    field, f"is larger than {MAX_ROBOT_JSON_BYTES} bytes; not a robot record"
                )
            spec = json.loads(record.read_text(encoding="utf-8"))
        except (OSError, ValueError, RecursionError) as error:
            reason = "nested too deeply" if isinstance(error, RecursionError) else _short(error)
            raise ConfigError(field, f"malformed robot record: {reason}") from None
        if not isinstance(spec, dict) or not isinstance(spec.get("type"), str):
            raise ConfigError(field, 'expected {"type": NAME, "params": {...}} (the robot block)')
        params = spec.get("params") or {}
        if not isinstance(params, dict) or "type" in params:
            raise ConfigError(f"{field}: params", "must be an object of robot parameters")
        return {"type": spec["type"], "params": params}

    def write_robot_record(
        self, experiment_dir: Path, robot_type: str, params: dict[str, Any]
    ) -> Path:
        """Write ``<experiment>/robot.json`` atomically so a later replay rebuilds the robot.

        Raises:
            OutputPathError: The file would leave the folder.
        """
        experiment_dir.mkdir(parents=True, exist_ok=True)
        path = self.robot_json(experiment_dir)
        ensure_inside(self.path, path)
        text = json.dumps({"type": robot_type, "params": params}, indent=1, default=str)
        atomic_write_bytes(path, (text + "\n").encode("utf-8"))
        return path

    def read_text(self, path: Path) -> str:
        """A text file of the folder; refuses links out of it and non-UTF-8 bytes.

        Raises:
            OutputPathError: ``path`` is outside the folder.
            ConfigError: Not UTF-8, or unreadable.
        """
        ensure_inside(self.path, path)
        try:
            return path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            raise ConfigError(str(path), "not UTF-8 text; is this a results folder?") from None
        except OSError as error:
            raise ConfigError(str(path), f"cannot read: {error.strerror}") from None

    def summary_records(self, required: Sequence[str] = IDENTITY_COLUMNS) -> list[dict[str, str]]:
        """The rows of ``summary.csv`` as text cells (a cell missing from a truncated file is "").

        Args:
            required: Columns the file must have.

        Raises:
            ConfigError: No ``summary.csv``, not a readable CSV, or a required column missing.
        """
        path = self.path / SUMMARY_CSV
        if not path.is_file():
            raise ConfigError(str(path), "no summary.csv here; run an experiment first")
        text = self.read_text(path)
        try:
            reader = csv.DictReader(io.StringIO(text, newline=""))
            missing = [c for c in required if c not in (reader.fieldnames or ())]
            if missing:
                raise ConfigError(str(path), f"missing columns {', '.join(missing)}")
            return [
                {str(k): (v if isinstance(v, str) else "") for k, v in record.items()}
                for record in reader
            ]
        except csv.Error as error:
            raise ConfigError(str(path), f"not a readable CSV: {str(error)[:120]}") from None


def _short(error: BaseException) -> str:
    text = str(error).splitlines()[0] if str(error) else type(error).__name__
    return text if len(text) <= 120 else text[:117] + "..."
