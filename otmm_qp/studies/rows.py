"""Read a study folder: its config and one typed table, the reference joined, success judged once.

:func:`load` is the public reader (``otmm_qp.studies.load``)::

    from otmm_qp.studies import load
    table = load("results/planar")          # pyarrow.Table, one row per episode
    frame = table.to_pandas()

Every declared column (:data:`~otmm_qp.studies.columns.EPISODE_COLUMNS`) is there in its
declared type; each task's ``reference.*`` columns (from its ``oracle`` row) are joined onto
its other rows; ``success`` and ``failure_causes`` are judged here, once, by
:func:`~otmm_qp.studies.criteria.failure_causes`; ``oracle_relative_error`` =
``max_error − reference.max_error`` [m], defined (not null) only for the rows that kept every
limit (``kept_limits``: the reference is the optimum *within* the limits). Only the rows of
the study ``study.json`` names are read; what was left out, and parts of an older schema, are
said in one line each.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pyarrow as pa

from otmm_qp.exceptions import OtmmError
from otmm_qp.studies.columns import (
    DERIVED_COLUMNS,
    KEPT_LIMITS,
    KEPT_REFERENCE_LIMITS,
    REFERENCE_NAME,
    judged_columns,
    number,
    task_reference,
)
from otmm_qp.studies.criteria import failure_causes
from otmm_qp.studies.limit_keeping import LIMIT_CAUSES
from otmm_qp.studies.schema import StudyConfig
from otmm_qp.studies.storage import read_study_folder

#: Oracle-relative error column computed for every controller row [m].
RELATIVE_ERROR = "oracle_relative_error"
#: Prefix of the task-level reference columns joined onto every row of a task.
REFERENCE_PREFIX = "reference."


@dataclass(frozen=True)
class StudyFrame:
    """A study read from its folder.

    Attributes:
        config: The validated study config of ``study.json``.
        table: One row per episode (see the module docstring).
        ignored: One line per reason something was left out.
        older: Parts of an older schema that were read (types converted to the declared ones).
        rows: The same judged rows as dicts (``table.to_pylist()`` with ``failure_causes``
            as tuples), made once by :func:`read` from the dicts it judged; what
            :func:`load_rows` returns.
    """

    config: StudyConfig
    table: pa.Table
    ignored: tuple[str, ...] = ()
    older: int = 0
    rows: Rows = field(default_factory=lambda: Rows([]), repr=False, compare=False)

    def notes(self) -> list[str]:
        """What a reader should be told: parts left out, parts of an older schema."""
        lines = [f"ignored {line}" for line in self.ignored]
        if self.older:
            lines.append(
                f"{self.older} parts are of an older episode schema (before version 2); "
                "read with the declared column types"
            )
        return lines


def is_reference(row: dict[str, Any]) -> bool:
    """Whether ``row`` is a task's offline reference (``controller == "oracle"``)."""
    return row.get("controller") == REFERENCE_NAME


def _known(value: Any) -> bool:
    return value is not None and not (isinstance(value, float) and math.isnan(value))


def task_of(row: dict[str, Any]) -> object:
    """The task an episode ran on: ``task_id`` when stored, else its identity columns."""
    return row.get("task_id") or (
        row["robot"],
        row["generator"],
        row.get("generator_params"),
        row["task_index"],
    )


def join_reference(rows: list[dict[str, Any]]) -> None:
    """Copy each ``oracle`` row's ``reference.*`` columns onto the rows of its task, in place.

    Columns already on a row are kept; ``reference.max_error`` falls back to the oracle row's
    ``max_error`` and ``reference.final_error`` is its ``final_error``.
    """
    references: dict[object, dict[str, Any]] = {}
    for row in rows:
        if is_reference(row):
            references[task_of(row)] = task_reference(row)
    for row in rows:
        for name, value in references.get(task_of(row), {}).items():
            if not _known(row.get(name)):
                row[name] = value


def kept_limits(row: dict[str, Any]) -> bool:
    """Whether a judged row kept every limit (so its oracle-relative error is defined).

    The reference row always does. Another row does when it ran to the end (``status`` ok,
    ``completed``), has no limit failure cause (:data:`LIMIT_CAUSES`: the study's speed and
    position-limit criteria) and its path kept the reference's own limits
    (``within_reference_limits`` not false; null in parts stored before the column).
    """
    return _kept(row, row.get("failure_causes", ()))


def _kept(row: dict[str, Any], causes: Sequence[str]) -> bool:
    """:func:`kept_limits` of ``row`` whose failure causes are ``causes``."""
    if is_reference(row):
        return True
    if row.get("status") != "ok" or not row.get("completed"):
        return False
    if any(cause in LIMIT_CAUSES for cause in causes):
        return False
    return row.get(KEPT_REFERENCE_LIMITS) is not False


def relative_error(row: dict[str, Any]) -> float | None:
    """``max_error − reference.max_error`` [m]; None (null) for a row that broke a limit.

    Every row that kept every limit (:func:`kept_limits`) was a candidate of its reference,
    which is never above it, so the value is ``≥ 0`` wherever it is defined; a row that broke
    a limit may have bought accuracy with it, and a reference within the limits is no
    yardstick for it. NaN without a reference.
    """
    return _relative(row) if row.get(KEPT_LIMITS) else None


def _relative(row: dict[str, Any]) -> float:
    """``max_error − reference.max_error`` [m] (NaN when either is missing)."""
    return number(row, "max_error") - number(row, "reference.max_error")


def judged_rows(config: StudyConfig, rows: list[dict[str, Any]]) -> None:
    """Join the references and judge every row once, in place.

    ``failure_causes``, ``success``, :data:`KEPT_LIMITS` (:func:`kept_limits`) and
    :data:`RELATIVE_ERROR` (:func:`relative_error`), composed by
    :func:`~otmm_qp.studies.columns.judged_columns`.
    """
    join_reference(rows)
    for row in rows:
        causes = () if is_reference(row) else failure_causes(row, config.success)
        key = None if row.get("episode_id") else str(row.get("episode_key", ""))
        kept = _kept(row, causes)
        relative = _relative(row) if kept else None
        row.update(judged_columns(causes, kept, relative, key))


@dataclass
class Rows:
    """Episode rows as Python dicts, with success and failure causes recomputed.

    ``controllers()`` lists the competitors only; the ``oracle`` rows are in ``rows`` too
    (select them with ``controller=REFERENCE_NAME``).
    """

    rows: list[dict[str, Any]]
    #: ``keys → (rows list id, its length, values → rows)``: :meth:`select`'s indexes, rebuilt
    #: when ``rows`` is replaced or grows (None: a key's values are not hashable).
    _indexes: dict[tuple[str, ...], Any] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )

    def controllers(self) -> list[str]:
        """Competing controllers in first-seen order (the reference excluded)."""
        return list(dict.fromkeys(r["controller"] for r in self.rows if not is_reference(r)))

    def robots(self) -> list[str]:
        """Robots in first-seen order."""
        return list(dict.fromkeys(r["robot"] for r in self.rows))

    def select(self, **equal: Any) -> list[dict[str, Any]]:
        """Rows whose columns equal the given values, in their order.

        Served from an index per set of columns (built on first use, O(rows); a report asks
        thousands of times); values that are not hashable fall back to a scan.
        """
        keys = tuple(sorted(equal))
        wanted = tuple(equal[k] for k in keys)
        index = self._index(keys)
        if index is not None:
            try:
                return list(index.get(wanted, ()))
            except TypeError:  # an unhashable value asked for
                pass
        return [r for r in self.rows if all(r.get(k) == v for k, v in equal.items())]

    def _index(self, keys: tuple[str, ...]) -> dict[tuple[Any, ...], list[dict[str, Any]]] | None:
        """``values → rows`` for ``keys`` (None when a row's value is not hashable)."""
        stamp = (id(self.rows), len(self.rows))
        cached = self._indexes.get(keys)
        if cached is not None and cached[0] == stamp:
            return cached[1]
        index: dict[tuple[Any, ...], list[dict[str, Any]]] | None = {}
        try:
            for row in self.rows:
                index.setdefault(tuple(row.get(k) for k in keys), []).append(row)  # type: ignore[union-attr]
        except TypeError:
            index = None
        self._indexes[keys] = (stamp, index)
        return index

    def information_labels(self) -> dict[str, str]:
        """``row name → information class`` (``causal``, ``preview H s``, ``offline``).

        Empty unless the competing rows carry more than one class (a study without preview
        rows, or stored before the ``information`` column, is labelled as before: not at all).
        The reference rows are labelled too when the others are.
        """
        classes: dict[str, str] = {}
        for row in self.rows:
            value = row.get("information")
            if isinstance(value, str) and value:
                classes.setdefault(str(row["controller"]), value)
        competing = {v for k, v in classes.items() if k != REFERENCE_NAME}
        return classes if len(competing) > 1 else {}

    @property
    def has_reference(self) -> bool:
        """Whether any task has an offline reference."""
        return any(is_reference(r) or _known(r.get("reference.achievable")) for r in self.rows)

    def accuracy_metric(self) -> str:
        """The headline accuracy column: oracle-relative error, or max error without reference."""
        return RELATIVE_ERROR if self.has_reference else "max_error"


def task_key(row: dict[str, Any]) -> tuple[object, ...]:
    """The task an episode ran on (``task_id`` when stored) and its loop mode."""
    return (task_of(row), row["loop_mode"])


def read(out: str | Path) -> StudyFrame:
    """The study in ``out``: config and judged table (see the module docstring).

    Raises:
        OtmmError: No study marker, an invalid one, or no episodes in ``out``.
    """
    out = Path(out)
    config, data = read_study_folder(out)
    if data.table is None or data.table.num_rows == 0:
        raise OtmmError(f"{out}: the study has no stored episodes yet")
    stored = data.table
    schema = stored.schema
    appended = [c for c in DERIVED_COLUMNS if schema.get_field_index(c.name) < 0]
    for column in appended:
        schema = schema.append(pa.field(column.name, column.type))
    rows = stored.to_pylist()  # judging is per row (criteria, joins): the one conversion
    for row in rows:  # every row holds the schema's columns, in its order (as to_pylist would)
        row.update(dict.fromkeys(c.name for c in appended))
    judged_rows(config, rows)
    table = _judged_table(stored, schema, rows)
    return StudyFrame(config, table, tuple(data.ignored), data.older, Rows(rows))


def _judged_table(stored: pa.Table, schema: pa.Schema, rows: list[dict[str, Any]]) -> pa.Table:
    """``stored`` with the columns :func:`judged_rows` sets replaced or appended (``schema``).

    Only those columns are converted back (the joined ``reference.*``, ``success``,
    ``episode_id`` and :data:`~otmm_qp.studies.columns.DERIVED_COLUMNS`); the others stay the
    stored Arrow arrays. Equal to ``pa.Table.from_pylist(rows, schema=schema)``.
    """
    judged = {"success", "episode_id", *(c.name for c in DERIVED_COLUMNS)}
    table = stored
    for position, spec in enumerate(schema):
        if spec.name not in judged and not spec.name.startswith(REFERENCE_PREFIX):
            continue
        values = pa.array([row[spec.name] for row in rows], spec.type)
        if position < table.num_columns:
            table = table.set_column(position, spec, values)
        else:
            table = table.append_column(spec, values)
    return table.replace_schema_metadata(schema.metadata)


def load(out: str | Path) -> pa.Table:
    """One row per episode of the study in ``out``, the reference joined and success judged.

    What was left out and parts of an older schema are printed on stderr, one line each.

    Raises:
        OtmmError: No study marker, an invalid one, or no episodes in ``out``.
    """
    frame = read(out)
    for line in frame.notes():
        print(f"otmm-qp: {line}", file=sys.stderr)
    return frame.table


def load_rows(out: str | Path) -> tuple[StudyConfig, Rows]:
    """The study config and its judged rows as dicts (:attr:`StudyFrame.rows` of :func:`read`).

    What the reader left out (other studies' parts, symlinks, duplicates...) and parts of an
    older schema are printed on stderr, one line each.

    Raises:
        OtmmError: No study marker, an invalid one, or no episodes in ``out``.
    """
    frame = read(Path(out))
    for line in frame.notes():
        print(f"otmm-qp: report {line}", file=sys.stderr)
    return frame.config, frame.rows
