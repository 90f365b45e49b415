"""The study dataset on disk: Parquet part files, a ``study.json`` marker, resume keys.

Layout of an output directory::

    study.json                    # marker: study name, file, config, counts (contracts §3)
    episodes/part-<run>-<n>.parquet  # one row per episode, each part written atomically
    timeseries/part-<run>-<n>.parquet  # sampled time series (optional)

Every part is complete or absent (atomic rename), so an interrupted study is always a
readable dataset; ``read_episodes`` concatenates the parts, promoting column types.
"""

from __future__ import annotations

import io
import json
import shutil
import time
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from otmm_qp.exceptions import ConfigError, OtmmError
from otmm_qp.output.paths import atomic_write_bytes, atomic_write_text, ensure_inside

MARKER = "study.json"
EPISODES = "episodes"
SERIES = "timeseries"


class StudyDirectoryError(ConfigError):
    """The output directory holds another study, or cannot be written."""


def read_marker(out: Path) -> dict[str, Any] | None:
    """The ``study.json`` record of ``out``, or None when there is none."""
    marker = out / MARKER
    if not marker.is_file():
        return None
    try:
        data = json.loads(marker.read_text())
    except (OSError, ValueError) as error:
        raise StudyDirectoryError(str(marker), f"unreadable study marker: {error}") from None
    return data if isinstance(data, dict) else None


def prepare_directory(out: Path, study: str, force: bool) -> None:
    """Create ``out`` or check it belongs to ``study``.

    With ``force``, the dataset of another study in ``out`` is removed first.

    Raises:
        StudyDirectoryError: ``out`` holds a different study (without ``force``), holds
            unrelated files, or cannot be created.
    """
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise StudyDirectoryError(
            str(out), f"cannot create the output directory: {error.strerror}"
        ) from None
    marker = read_marker(out)
    if marker is not None and marker.get("study") != study:
        if not force:
            raise StudyDirectoryError(
                str(out),
                f"holds study {marker.get('study')!r}, not {study!r}; "
                "choose another --out or pass --force to replace it",
            )
        for name in (EPISODES, SERIES):
            target = ensure_inside(out, out / name)
            if target.is_dir():
                shutil.rmtree(target)
        (out / MARKER).unlink()


def write_marker(out: Path, record: dict[str, Any]) -> None:
    """Write ``study.json`` atomically.

    Raises:
        StudyDirectoryError: The directory is not writable (disk full, permissions).
    """
    try:
        atomic_write_text(out / MARKER, json.dumps(record, indent=2, sort_keys=True, default=str))
    except OSError as error:
        raise StudyDirectoryError(str(out / MARKER), f"cannot write: {error.strerror}") from None


def _table(rows: list[dict[str, Any]]) -> pa.Table:
    columns: list[str] = []
    for row in rows:
        for name in row:
            if name not in columns:
                columns.append(name)
    return pa.Table.from_pylist([{c: row.get(c) for c in columns} for row in rows])


class PartWriter:
    """Writes numbered Parquet parts of one run into ``out/episodes`` and ``out/timeseries``."""

    def __init__(self, out: Path) -> None:
        self.out = out
        self.run = time.strftime("%Y%m%dT%H%M%S") + f"-{time.time_ns() % 1_000_000:06d}"
        self.count = 0

    def _write(self, folder: str, table: pa.Table) -> Path:
        directory = ensure_inside(self.out, self.out / folder)
        try:
            directory.mkdir(exist_ok=True)
        except OSError as error:
            raise StudyDirectoryError(str(directory), f"cannot write: {error.strerror}") from None
        buffer = io.BytesIO()
        pq.write_table(table, buffer)
        path = directory / f"part-{self.run}-{self.count:06d}.parquet"
        try:
            atomic_write_bytes(path, buffer.getvalue())
        except OSError as error:
            raise StudyDirectoryError(str(path), f"cannot write: {error.strerror}") from None
        return path

    def write(self, rows: list[dict[str, Any]], series: list[dict[str, Any]]) -> None:
        """Write one part of episode rows (and one of time series, if any)."""
        if not rows:
            return
        self._write(EPISODES, _table(rows))
        if series:
            merged: dict[str, list[Any]] = {}
            for block in series:
                for name, values in block.items():
                    merged.setdefault(name, []).extend(values)
            self._write(SERIES, pa.table(merged))
        self.count += 1


def _read_parts(folder: Path, columns: list[str] | None = None) -> pa.Table | None:
    if not folder.is_dir():
        return None
    tables = []
    for part in sorted(folder.glob("part-*.parquet")):
        try:
            table = pq.read_table(part)
        except (OSError, pa.ArrowInvalid) as error:
            raise OtmmError(f"{part}: unreadable Parquet part: {error}") from None
        if columns is not None:
            table = table.select([c for c in columns if c in table.column_names])
        tables.append(table)
    if not tables:
        return None
    return pa.concat_tables(tables, promote_options="permissive")


def read_episodes(out: Path, columns: list[str] | None = None) -> pa.Table | None:
    """Every stored episode row (all parts), or None when there are none."""
    return _read_parts(out / EPISODES, columns)


def read_series(out: Path) -> pa.Table | None:
    """Every stored time-series row, or None."""
    return _read_parts(out / SERIES)


def stored_keys(out: Path) -> set[str]:
    """Episode keys already in the dataset."""
    table = read_episodes(out, ["episode_key"])
    if table is None or "episode_key" not in table.column_names:
        return set()
    return set(table.column("episode_key").to_pylist())
