"""The declared columns of a study's episode rows: one Arrow schema written with every part.

:data:`EPISODE_COLUMNS` is the one declaration list: name, Arrow type and meaning of every
column a study row may hold. Every Parquet part under ``DIR/episodes`` is written with all of
them (a value a row lacks is null), plus the ``task.*`` descriptors of the study's generators
(:func:`descriptor_type`), so ``pyarrow.dataset``, ``pandas.read_parquet``, DuckDB and polars
read a study folder directly. A part records :data:`SCHEMA_VERSION` in its Parquet metadata;
parts written before it (column types inferred per part) are read by
:func:`otmm_qp.studies.load`, which says so in one line.

A new column is one :class:`Column` line here (and its value where the row is filled); the
column reference in ``docs/studies.md`` is generated from this list
(``python -m otmm_qp.studies.columns``, checked by a test).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pyarrow as pa

from otmm_qp.metrics.table import METRICS, STUDY_METRICS, Metric

#: Version of the episode schema written with every part (Parquet metadata).
SCHEMA_VERSION = 2
#: Parquet schema-metadata key holding :data:`SCHEMA_VERSION`.
SCHEMA_VERSION_KEY = b"otmm_qp.schema_version"
#: Prefix of the per-generator task descriptor columns.
TASK_PREFIX = "task."


@dataclass(frozen=True)
class Column:
    """One declared episode column.

    Attributes:
        name: Column name.
        type: Arrow type (every column is nullable except :data:`REQUIRED`).
        doc: One-line meaning, with the unit in brackets.
        group: Section of the column reference (identity, controller, metric, reference, outcome).
    """

    name: str
    type: pa.DataType
    doc: str
    group: str


def _metric_type(metric: Metric) -> pa.DataType:
    """Counts (format ``d``/``.0f``) are int64, flags (format ``""``) bool, the rest float64."""
    if metric.fmt in ("d", ".0f"):
        return pa.int64()
    if metric.fmt == "":
        return pa.bool_()
    return pa.float64()


def _metric_doc(metric: Metric) -> str:
    return f"{metric.label} [{metric.unit}]" if metric.unit else metric.label


_S, _I, _F, _B = pa.string(), pa.int64(), pa.float64(), pa.bool_()

_IDENTITY = (
    ("study", _S, "study name"),
    ("episode_key", _S, "SHA-256 of everything that sets the episode's numbers (the row's key)"),
    ("task_id", _S, "robot/label/index of the task"),
    ("episode_id", _S, "first 10 hex digits of episode_key (otmm-qp study show --episode)"),
    ("robot", _S, "robot name in the study"),
    ("generator", _S, "task generator type"),
    ("generator_entry", _S, "label of the generator entry (its name, or type#position)"),
    ("generator_params", _S, "generator parameters, canonical JSON"),
    ("task_index", _I, "index of the task within its generator entry"),
    ("task_seed", _I, "seed the task was drawn from"),
)
_CONTROLLER = (
    ("controller", _S, "controller name (oracle: the task's offline reference)"),
    ("filters", _S, "task filters joined by '+', or none"),
    ("backend", _S, "backend type"),
    ("controller_params", _S, "filter and backend parameters, canonical JSON"),
    ("loop_mode", _S, "open or clik (offline: the reference)"),
    ("information", _S, "what the row knew of the task: causal, preview H s, or offline"),
    ("plant", _S, "label of the plants axis value (null without a plants axis)"),
    ("dt", _F, "control period [s]"),
    ("duration", _F, "episode duration: the task's plus duration.extra, capped [s]"),
)
#: ``reference.*`` columns (the offline reference of the task), in order.
_REFERENCE = (
    ("reference.status", _S, "achievable, unachievable, undecided or failed"),
    ("reference.max_error", _F, "the position optimum: smallest max position error found [m]"),
    ("reference.max_orientation_error", _F, "its largest orientation error [rad]"),
    ("reference.max_joint_speed", _F, "its largest joint speed [rad/s]"),
    ("reference.touches_position_limit", _B, "whether its path touches a position limit"),
    ("reference.min_sigma", _F, "smallest σ_min along the task's own path (its IK start)"),
    (
        "reference.near_singular",
        _B,
        "whether the task's own path comes within σ_S of a singularity",
    ),
    ("reference.achievable", _B, "whether the reference meets the tolerances (a certificate)"),
    ("reference.upper", _F, "merit of the best path within the limits [tolerances]"),
    ("reference.lower", _F, "certified lower bound of the min-max merit [tolerances]"),
    ("reference.position_error", _F, "largest position error of the best-merit path [m]"),
    ("reference.position_lower", _F, "certified lower bound of the max position error [m]"),
    ("reference.source", _S, "where the best path came from (a start or a controller)"),
    ("reference.step", _F, "last step of the solve (its convergence test) [tolerances]"),
    ("reference.kkt_residual", _F, "KKT residual of the solve's end [tolerances]"),
    ("reference.converged", _B, "whether the solve stopped on its convergence test"),
    ("reference.iterations", _I, "QPs the solve took"),
    (
        "reference.certificate",
        _S,
        "which bound sets reference.lower at which sample: kind@k "
        "(reach, travel, turn, start, search; none)",
    ),
    ("reference.seconds", _F, "wall-clock time of the reference solve [s]"),
)
_OUTCOME = (
    ("status", _S, "ok, stopped (ended early) or error (never ran)"),
    ("error_message", _S, "one-line error or stop reason (null when none)"),
    ("success", _B, "success as judged when the row was stored (load() judges it again)"),
    (
        "within_reference_limits",
        _B,
        "whether its path, from q0 to the end, kept the limits its reference keeps (position "
        "limits, every step within the reference's v_max dt); null: no reference",
    ),
)
_STUDY_RATIOS = tuple(m for m in STUDY_METRICS if m.name != "oracle_relative_error")

#: Every declared episode column, in the order a part stores them (``task.*`` follow).
EPISODE_COLUMNS: tuple[Column, ...] = (
    *(Column(n, t, d, "identity") for n, t, d in _IDENTITY),
    *(Column(n, t, d, "controller") for n, t, d in _CONTROLLER),
    *(Column(m.name, _metric_type(m), _metric_doc(m), "metric") for m in METRICS),
    *(Column(n, t, d, "reference") for n, t, d in _REFERENCE),
    *(Column(n, t, d, "outcome") for n, t, d in _OUTCOME),
    *(Column(m.name, _metric_type(m), _metric_doc(m), "metric") for m in _STUDY_RATIOS),
)
#: Stored column: whether a row's path kept the limits of its task's reference.
KEPT_REFERENCE_LIMITS = "within_reference_limits"
#: Derived column: whether a row kept every limit (its oracle-relative error is defined).
KEPT_LIMITS = "kept_limits"
#: Columns no stored row lacks.
REQUIRED = ("study", "episode_key")
#: Columns :func:`otmm_qp.studies.load` adds (judged once, on read).
DERIVED_COLUMNS: tuple[Column, ...] = (
    Column(
        "reference.final_error",
        _F,
        "the reference's final position error (its oracle row's final_error) [m]",
        "derived",
    ),
    Column(
        "kept_limits",
        _B,
        "whether the row kept every limit: ran to the end, no speed or position_limit failure "
        "cause, within_reference_limits not false (the reference row: true)",
        "derived",
    ),
    Column(
        "oracle_relative_error",
        _F,
        "max_error − reference.max_error [m], defined only where kept_limits (null for a row "
        "that broke a limit; NaN without a reference); ≥ 0 by construction",
        "derived",
    ),
    Column("failure_causes", pa.list_(_S), "why the episode failed (empty: a success)", "derived"),
)
_BY_NAME = {c.name: c for c in EPISODE_COLUMNS}


def declared(name: str) -> Column | None:
    """The declared column ``name``, or None (a ``task.*`` descriptor or unknown)."""
    return _BY_NAME.get(name)


def number(row: Mapping[str, Any], name: str) -> float:
    """A row's numeric column as float: NaN when absent, null or text (the one accessor)."""
    value = row.get(name)
    if value is None or isinstance(value, (str, bytes)):
        return math.nan
    return float(value)


def descriptor_type(values: Iterable[Any]) -> pa.DataType:
    """Arrow type of a ``task.*`` descriptor column: bool, string or float64 (any number).

    Integers are stored as float64, so two tasks of one generator never disagree.
    """
    known = [v for v in values if v is not None]
    if known and all(isinstance(v, (bool, np.bool_)) for v in known):
        return _B
    if known and all(isinstance(v, str) for v in known):
        return _S
    return _F


def episode_schema(extra: Mapping[str, pa.DataType] | None = None) -> pa.Schema:
    """The declared schema plus ``extra`` columns (the study's ``task.*`` descriptors)."""
    fields = [pa.field(c.name, c.type, nullable=c.name not in REQUIRED) for c in EPISODE_COLUMNS]
    fields += [pa.field(n, t) for n, t in (extra or {}).items() if n not in _BY_NAME]
    metadata = {SCHEMA_VERSION_KEY: str(SCHEMA_VERSION).encode("ascii")}
    return pa.schema(fields, metadata=metadata)


def extra_columns(
    rows: Sequence[Mapping[str, Any]], known: Mapping[str, pa.DataType] | None = None
) -> dict[str, pa.DataType]:
    """``known`` plus the undeclared columns of ``rows`` (``task.*`` descriptors), typed.

    A new column whose values are all null is left out until a value gives it a type (so
    no part stores an untyped column another part would clash with).
    """
    extra = dict(known or {})
    for row in rows:
        for name, value in row.items():
            if value is not None and name not in _BY_NAME and name not in extra:
                extra[name] = descriptor_type(r.get(name) for r in rows)
    return extra


def episode_table(
    rows: Sequence[Mapping[str, Any]], known: Mapping[str, pa.DataType] | None = None
) -> pa.Table:
    """Episode rows as a table of :func:`episode_schema` (missing values null)."""
    schema = episode_schema(extra_columns(rows, known))
    arrays = [pa.array([row.get(f.name) for row in rows], f.type) for f in schema]
    return pa.Table.from_arrays(arrays, schema=schema)


def markdown_reference() -> str:
    """The column reference of ``docs/studies.md`` (Markdown table), from the declarations."""
    lines = ["| column | type | meaning |", "|---|---|---|"]
    for column in (*EPISODE_COLUMNS, *DERIVED_COLUMNS):
        lines.append(f"| `{column.name}` | {column.type} | {column.doc} |")
    lines.append(
        "| `task.*` | double, string or bool | the generator's descriptors of the task "
        "(numbers as double) |"
    )
    return "\n".join(lines)


#: Markers around the generated table in ``docs/studies.md``.
DOC_BEGIN = "<!-- episode columns: generated by python -m otmm_qp.studies.columns -->"
DOC_END = "<!-- end of episode columns -->"


def main() -> int:
    """Print the column reference (between its markers) for ``docs/studies.md``."""
    print(f"{DOC_BEGIN}\n{markdown_reference()}\n{DOC_END}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
