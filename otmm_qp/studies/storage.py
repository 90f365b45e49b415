"""The study dataset on disk: Parquet part files, a ``study.json`` marker, resume keys.

Layout of an output directory::

    study.json                    # marker: study name, id, file, config, episode keys
    episodes/part-<run>-<n>.parquet  # one row per episode, each part written atomically
    timeseries/part-<run>-<n>.parquet  # sampled time series (optional)

Every part is complete or absent (atomic rename), so an interrupted study is always a
readable dataset. Each part records the *study id* (a digest of the study's config) in its
Parquet metadata. Readers (:func:`read_study`, the report, ``--resume``) take only the rows of
this study and this plan: parts of another study id, symlinked parts or folders, unreadable or
foreign Parquet files, parts whose column types clash, rows whose episode key the plan does
not hold, and second copies of an episode are left out, and every reason is reported in
:attr:`StudyData.ignored`.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import stat
import time
from collections import Counter
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pyarrow as pa
import pyarrow.parquet as pq

from otmm_qp.exceptions import ConfigError
from otmm_qp.output.folders import remove_kind_files
from otmm_qp.paths import atomic_write_bytes, atomic_write_text, ensure_inside
from otmm_qp.studies.columns import (
    SCHEMA_VERSION,
    SCHEMA_VERSION_KEY,
    episode_schema,
    episode_table,
    extra_columns,
)

if TYPE_CHECKING:
    from otmm_qp.studies.schema import StudyConfig

MARKER = "study.json"
EPISODES = "episodes"
SERIES = "timeseries"
#: Parquet schema-metadata key holding the study id of a part.
STUDY_ID_KEY = b"otmm_qp.study_id"
#: Largest ``study.json`` read [bytes].
MAX_MARKER_BYTES = 64 * 1024 * 1024
#: Largest Parquet part read [bytes].
MAX_PART_BYTES = 2 * 1024**3


class StudyDirectoryError(ConfigError):
    """The output directory holds another study, or cannot be written."""


def study_id(config: dict[str, Any], whole: bool = False) -> str:
    """The id of a study: SHA-256 (16 hex digits) of its config's canonical JSON.

    A study that sizes itself (a ``decide`` block) is hashed without that block and without
    the generators' counts (its budget's split): raising or lowering ``budget_tasks`` or
    ``batch`` keeps the id, so the stored episodes are resumed (their keys never held the
    counts). Studies without ``decide`` hash their config whole, as before; ``whole`` hashes
    a ``decide`` study whole too (the id such a folder recorded before issue 36).
    """
    if config.get("decide") is not None and not whole:
        generators = [
            {k: v for k, v in g.items() if k != "count"} if isinstance(g, dict) else g
            for g in config.get("generators") or []
        ]
        config = {**{k: v for k, v in config.items() if k != "decide"}, "generators": generators}
    text = json.dumps(config, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def _read_regular(path: Path, limit: int) -> bytes:
    """The bytes of ``path``, refusing a symlink, a non-regular file or more than ``limit``."""
    fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise OSError(0, "not a regular file")
        if info.st_size > limit:
            raise OSError(0, f"larger than {limit} bytes")
        with os.fdopen(fd, "rb", closefd=False) as handle:
            data = handle.read(info.st_size + 1)  # a buffer sized to the file, never to limit
        if len(data) > limit:
            raise OSError(0, f"larger than {limit} bytes")
        return data
    finally:
        os.close(fd)


def read_marker(out: Path) -> dict[str, Any] | None:
    """The ``study.json`` record of ``out``, or None when there is none.

    Raises:
        StudyDirectoryError: ``study.json`` is a symlink, not a file, unreadable or not a
            JSON object.
    """
    marker = out / MARKER
    if marker.is_symlink():
        raise StudyDirectoryError(str(marker), "is a symlink; a study marker must be a plain file")
    if not marker.exists():
        return None
    try:
        data = json.loads(_read_regular(marker, MAX_MARKER_BYTES).decode("utf-8"))
    except (OSError, ValueError) as error:
        reason = error.strerror if isinstance(error, OSError) and error.strerror else error
        raise StudyDirectoryError(str(marker), f"unreadable study marker: {reason}") from None
    if not isinstance(data, dict):
        raise StudyDirectoryError(str(marker), "is not a study marker (a JSON object expected)")
    return data


def arms_of(config: Mapping[str, Any]) -> list[Any]:
    """What a study is of: the ``robot`` block of each of its robots (arm, frame, task)."""
    robots = config.get("robots")
    if not isinstance(robots, list):
        return []
    return [entry.get("robot") if isinstance(entry, Mapping) else entry for entry in robots]


def other_study(marker: Mapping[str, Any], config: Mapping[str, Any]) -> str | None:
    """Why the study ``marker`` records is another study than ``config`` (None: the same).

    A study is its name and what it is of (:func:`arms_of`: the same arm with another task
    is another study); its other settings may change between runs of it (resume keeps the
    episodes whose keys still match).
    """
    name = config.get("name")
    if marker.get("study") != name:
        return f"holds study {marker.get('study')!r}, not {name!r}"
    recorded = marker.get("config")
    if isinstance(recorded, Mapping) and arms_of(recorded) != arms_of(config):
        return f"holds another study named {name!r} (of other robots or another task)"
    return None


def prepare_directory(out: Path, config: Mapping[str, Any], force: bool) -> None:
    """Check the (claimed) folder ``out`` belongs to the study ``config`` (its JSON dump).

    A folder holding another study's ``study.json`` (:func:`other_study`) is refused, whether
    or not that study's run is still going. With ``force``, everything another study wrote in
    ``out`` (dataset, marker, report and figures) is removed first.

    Raises:
        StudyDirectoryError: ``out`` holds a different study (without ``force``), or an
            unreadable marker.
    """
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise StudyDirectoryError(
            str(out), f"cannot create the output directory: {error.strerror}"
        ) from None
    for name in (EPISODES, SERIES):
        if (out / name).is_symlink():
            raise StudyDirectoryError(
                str(out / name), "is a symlink; the dataset must lie inside the output folder"
            )
    try:
        marker = read_marker(out)
    except StudyDirectoryError:
        if not force:
            raise
        marker = {}
    reason = None if marker is None else other_study(marker, config)
    if reason is not None:
        if not force:
            raise StudyDirectoryError(
                str(out), f"{reason}; choose another --out or pass --force to replace it"
            )
        remove_kind_files(out, "study")


def write_marker(out: Path, record: dict[str, Any]) -> None:
    """Write ``study.json`` atomically.

    Raises:
        StudyDirectoryError: The directory is not writable (disk full, permissions).
    """
    try:
        atomic_write_text(out / MARKER, json.dumps(record, indent=2, sort_keys=True, default=str))
    except OSError as error:
        raise StudyDirectoryError(str(out / MARKER), f"cannot write: {error.strerror}") from None


class PartWriter:
    """Writes numbered Parquet parts of one run into ``out/episodes`` and ``out/timeseries``.

    Each part carries ``study`` (a :func:`study_id`) and the schema version in its Parquet
    metadata; episode parts have the declared schema (:mod:`otmm_qp.studies.columns`) plus
    every ``task.*`` column known so far (``task_columns``, then those the rows bring).
    """

    def __init__(
        self, out: Path, study: str = "", task_columns: dict[str, pa.DataType] | None = None
    ) -> None:
        self.out = out
        self.study = study
        self.task_columns = dict(task_columns or {})
        self.run = time.strftime("%Y%m%dT%H%M%S") + f"-{time.time_ns() % 1_000_000:06d}"
        self.count = 0

    def _write(self, folder: str, table: pa.Table) -> Path:
        directory = ensure_inside(self.out, self.out / folder)
        try:
            directory.mkdir(exist_ok=True)
        except OSError as error:
            raise StudyDirectoryError(str(directory), f"cannot write: {error.strerror}") from None
        if self.study:
            metadata = dict(table.schema.metadata or {})
            metadata[STUDY_ID_KEY] = self.study.encode("ascii")
            table = table.replace_schema_metadata(metadata)
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
        self.task_columns = extra_columns(rows, self.task_columns)
        self._write(EPISODES, episode_table(rows, self.task_columns))
        if series:
            merged: dict[str, list[Any]] = {}
            for block in series:
                for name, values in block.items():
                    merged.setdefault(name, []).extend(values)
            self._write(SERIES, pa.table(merged))
        self.count += 1


@dataclass
class StudyData:
    """The rows of one study read from its folder, and what was left out.

    Attributes:
        table: The rows (one per episode key, first stored copy), or None when there are none.
        ignored: One line per reason something was left out (part names cut, counts).
        older: Parts read that were written before the declared schema (their types were
            inferred per part; they are read with the declared ones).
    """

    table: pa.Table | None
    ignored: list[str] = field(default_factory=list)
    older: int = 0


def _part_study(part: pq.ParquetFile) -> str | None:
    metadata = part.schema_arrow.metadata or {}
    value = metadata.get(STUDY_ID_KEY)
    return value.decode("ascii", "replace") if value is not None else None


def _open_part(path: Path) -> pq.ParquetFile:
    """A Parquet part opened without following symlinks, in a buffer sized to it (<= 2 GiB)."""
    return pq.ParquetFile(pa.BufferReader(_read_regular(path, MAX_PART_BYTES)))


def conform(table: pa.Table) -> pa.Table:
    """An episode part with every declared column, in the declared types (nulls where absent).

    Undeclared columns (``task.*`` descriptors) follow, as stored.

    Raises:
        pyarrow.ArrowException: A stored column cannot be cast to its declared type.
    """
    schema = episode_schema()
    names = set(table.column_names)
    arrays = [
        table.column(f.name).cast(f.type) if f.name in names else pa.nulls(len(table), f.type)
        for f in schema
    ]
    fields = list(schema.remove_metadata())
    for name in table.column_names:
        if schema.get_field_index(name) < 0:
            arrays.append(table.column(name))
            fields.append(table.schema.field(name))
    return pa.Table.from_arrays(arrays, schema=pa.schema(fields))


def _key_column(table: pa.Table) -> list[Any] | None:
    if "episode_key" not in table.column_names:
        return None
    column = table.column("episode_key")
    if not pa.types.is_string(column.type) and not pa.types.is_large_string(column.type):
        return None
    return column.to_pylist()


def read_study(
    out: Path,
    folder: str = EPISODES,
    study: str | None = None,
    keys: set[str] | None = None,
    columns: list[str] | None = None,
) -> StudyData:
    """The rows of study ``study`` in ``out/folder`` whose episode key ``keys`` holds.

    Args:
        out: The study folder.
        folder: :data:`EPISODES` or :data:`SERIES`.
        study: The study id parts must carry (None: any; parts without an id are taken).
        keys: Episode keys of the plan (None: any key).
        columns: Columns to keep (those present), or all.

    Returns:
        The rows, deduplicated by episode key for :data:`EPISODES` (first part in name order
        wins), and the reasons for what was left out.
    """
    ignored: Counter[str] = Counter()
    directory = out / folder
    if directory.is_symlink():
        return StudyData(None, [f"{folder}/ is a symlink out of the folder: not read"])
    if not directory.is_dir():
        return StudyData(None)
    tables: list[pa.Table] = []
    schema: pa.Schema | None = None
    seen: set[str] = set()
    older = 0
    for path in sorted(directory.iterdir()):
        if not (path.name.startswith("part-") and path.name.endswith(".parquet")):
            continue
        if path.is_symlink():
            ignored["symlinked parts"] += 1
            continue
        try:
            part = _open_part(path)
            if study is not None and _part_study(part) not in (None, study):
                ignored["parts of another study (or of earlier settings of this one)"] += 1
                continue
            table = part.read()
        except (OSError, pa.ArrowException, ValueError):
            ignored["unreadable or non-Parquet parts"] += 1
            continue
        version = (table.schema.metadata or {}).get(SCHEMA_VERSION_KEY)
        table = table.replace_schema_metadata(None)
        key_values = _key_column(table)
        if key_values is None:
            ignored["parts without a text episode_key column (not otmm-qp parts)"] += 1
            continue
        if folder == EPISODES:
            if version != str(SCHEMA_VERSION).encode("ascii"):
                older += 1
            try:
                table = conform(table)
            except (pa.ArrowException, ValueError):
                ignored["parts whose column types clash with the declared ones"] += 1
                continue
        if columns is not None:
            table = table.select([c for c in columns if c in table.column_names])
        try:
            merged = (
                table.schema
                if schema is None
                else pa.unify_schemas([schema, table.schema], promote_options="permissive")
            )
        except (pa.ArrowException, ValueError):
            ignored["parts whose column types clash with the other parts"] += 1
            continue
        mask = []
        for key in key_values:
            if keys is not None and key not in keys:
                ignored["rows of episodes not in this study's plan"] += 1
                mask.append(False)
            elif folder == EPISODES and key in seen:
                ignored["second copies of an episode"] += 1
                mask.append(False)
            else:
                mask.append(True)
        if folder == EPISODES:
            seen.update(k for k, m in zip(key_values, mask, strict=True) if m)
        if not any(mask):
            continue
        tables.append(table.filter(pa.array(mask, pa.bool_())))
        schema = merged
    lines = [f"{count} {reason}" for reason, count in ignored.items()]
    if not tables:
        return StudyData(None, lines, older)
    return StudyData(pa.concat_tables(tables, promote_options="permissive"), lines, older)


def _marker_scope(out: Path) -> tuple[str | None, set[str] | None]:
    """The study id and plan keys ``study.json`` records (None where it records none)."""
    try:
        marker = read_marker(out) or {}
    except StudyDirectoryError:
        return None, None
    ident = marker.get("study_id")
    keys = marker.get("episode_keys")
    return (
        ident if isinstance(ident, str) else None,
        {k for k in keys if isinstance(k, str)} if isinstance(keys, list) else None,
    )


def read_episodes(out: Path, columns: list[str] | None = None) -> pa.Table | None:
    """The stored episode rows of the study ``study.json`` names (see :func:`read_study`)."""
    ident, keys = _marker_scope(out)
    return read_study(out, EPISODES, ident, keys, columns).table


def read_series(out: Path) -> pa.Table | None:
    """The stored time-series rows of the study ``study.json`` names, or None."""
    ident, keys = _marker_scope(out)
    return read_study(out, SERIES, ident, keys).table


def stored_keys(out: Path, study: str | None = None, keys: set[str] | None = None) -> StudyData:
    """Episode keys of study ``study`` and plan ``keys`` already stored (``--resume``).

    Returns:
        A :class:`StudyData` with only the ``episode_key`` column, and what was left out.
    """
    return read_study(out, EPISODES, study, keys, ["episode_key"])


def read_study_folder(out: Path) -> tuple[StudyConfig, StudyData]:
    """The validated config of the study in ``out`` and its episode rows (this study's only).

    Raises:
        StudyDirectoryError: No ``study.json``, one without a valid study config, or one whose
            config is not the one its ``study_id`` was computed from (edited by hand).
    """
    from pydantic import ValidationError

    from otmm_qp.studies.schema import StudyConfig

    marker = read_marker(out)
    if marker is None:
        raise StudyDirectoryError(str(out), f"no {MARKER} here; not a study directory")
    if not isinstance(marker.get("config"), dict):
        raise StudyDirectoryError(str(out / MARKER), "holds no study config ('config' object)")
    try:
        config = StudyConfig.model_validate(marker["config"])
    except ValidationError as error:
        first = error.errors()[0]
        where = ".".join(str(p) for p in first["loc"]) or "config"
        raise StudyDirectoryError(
            str(out / MARKER), f"config.{where}: {first['msg']}"[:300]
        ) from None
    ident, keys = _marker_scope(out)
    # The id is the hash of the config as it was written (its stored JSON), not as today's
    # schema re-reads it: a folder written before a field was added still matches, and a
    # value edited by hand does not.
    if ident is not None and ident not in (
        study_id(marker["config"]),
        study_id(marker["config"], whole=True),  # a decide study stored before issue 36
    ):
        raise StudyDirectoryError(
            str(out / MARKER),
            f"its config does not hash to its study_id {ident!r:.20} (edited by hand?); "
            "re-run the study from its YAML file instead",
        )
    return config, read_study(out, EPISODES, ident, keys)


@contextlib.contextmanager
def writing_report(out: Path) -> Iterator[None]:
    """Turn an OS error while writing a study's report into one :class:`StudyDirectoryError`.

    A read-only or full folder then gives one line; the dataset is untouched.
    """
    try:
        yield
    except OSError as error:
        reason = error.strerror or str(error)
        raise StudyDirectoryError(str(out), f"cannot write the study report: {reason}") from None
