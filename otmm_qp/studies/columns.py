"""The declared columns of a study's episode rows: one Arrow schema written with every part.

:data:`EPISODE_COLUMNS` is the one declaration list: name, Arrow type and meaning of every
column a study row may hold. Every Parquet part under ``DIR/episodes`` is written with all of
them (a value a row lacks is null), plus the ``task.*`` descriptors of the study's generators
(:func:`descriptor_type`), so ``pyarrow.dataset``, ``pandas.read_parquet``, DuckDB and polars
read a study folder directly. A part records :data:`SCHEMA_VERSION` in its Parquet metadata;
parts written before it (column types inferred per part) are read by
:func:`otmm_qp.studies.load`, which says so in one line.

A new column is one :class:`Column` line here and its value in the group builder that fills
it (:func:`identity_columns`, :func:`controller_columns`, :func:`metric_columns`,
:func:`reference_columns`, ... composed by :func:`episode_row`, the one constructor of a stored
row, like optuna's ``FrozenTrial``); the column reference in ``docs/studies.md`` is generated
from this list (``python -m otmm_qp.studies.columns``, checked by a test).
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa

from otmm_qp.metrics.table import METRICS, STUDY_METRICS, Metric
from otmm_qp.output.markdown import Table, table_markdown
from otmm_qp.reference.result import REFERENCE_COLUMNS
from otmm_qp.studies.keys import episode_id
from otmm_qp.studies.task import OFFLINE, StudyTask, plant_name
from otmm_qp.studies.task_ids import entry_label, task_id

if TYPE_CHECKING:
    from otmm_qp.config.schema import ControllerConfig
    from otmm_qp.simulation.run_result import RunResult
    from otmm_qp.studies.schema import StudyConfig

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
        "(reach, travel, turn, wrist, start, search, coupled; none)",
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


# ---------------------------------------------------------------------------------------------
# Row builders: every stored episode row is composed of these groups (:func:`episode_row`), and
# no module builds a row any other way (``tests/studies/test_row_builders.py`` checks the code).
# ---------------------------------------------------------------------------------------------

#: A group of episode columns: ``column name → value`` (None: null).
Columns = dict[str, Any]
#: The reference rows' ``controller`` and ``backend`` names (the data contract with the report).
REFERENCE_NAME = "oracle"
#: The ``information`` column of the reference rows (the whole path, solved offline).
OFFLINE_INFORMATION = "offline"
_RATIO_NAMES = tuple(m.name for m in _STUDY_RATIOS)
_METRIC_NAMES = tuple(m.name for m in METRICS)
_DERIVED_NAMES = frozenset(c.name for c in DERIVED_COLUMNS)


def _canonical(value: Any) -> str:
    """Canonical JSON of a parameter record (sorted keys; anything else as its ``str``)."""
    return json.dumps(value, sort_keys=True, default=str)


def episode_row(*groups: Mapping[str, Any]) -> Columns:
    """One episode row composed of column groups: the one constructor of a stored row.

    Every name must be a declared column (:data:`EPISODE_COLUMNS`) or a ``task.*``
    descriptor, and no two groups may set the same column (each value has one source).

    Raises:
        ValueError: An undeclared column name, or a column two groups set.
    """
    row: Columns = {}
    for group in groups:
        for name, value in group.items():
            if name in row:
                raise ValueError(f"episode column {name!r} is set by two column groups")
            if name not in _BY_NAME and not name.startswith(TASK_PREFIX):
                raise ValueError(f"{name!r} is not a declared episode column (see columns.py)")
            row[name] = value
    return row


def identity_columns(config: StudyConfig, task: StudyTask, key: str) -> Columns:
    """Which study, episode and task a row is: the ``identity`` group."""
    gen = config.generators[task.generator]
    return {
        "study": config.name,
        "episode_key": key,
        "task_id": task_id(config, task.robot, task.generator, task.index),
        "episode_id": episode_id(key),
        "robot": config.robots[task.robot].name,
        "generator": gen.type,
        "generator_entry": entry_label(config, task.generator),
        "generator_params": _canonical(gen.params),
        "task_index": task.index,
        "task_seed": task.seed,
    }


def controller_columns(config: StudyConfig, spec: ControllerConfig, mode: str) -> Columns:
    """What ran: a study controller in loop ``mode`` (``plant`` only with a plants axis), ``dt``.

    ``information`` is the built backend's, so it is its own group (:func:`information_columns`).
    """
    params = {
        **{f"{f.type}.{k}": v for f in spec.filters for k, v in f.params.items()},
        **{f"{spec.backend.type}.{k}": v for k, v in spec.backend.params.items()},
    }
    columns: Columns = {
        "controller": spec.name,
        "filters": "+".join(f.type for f in spec.filters) or "none",
        "backend": spec.backend.type,
        "controller_params": _canonical(params),
        "loop_mode": mode,
        "dt": config.dt,
    }
    if config.plants is not None:
        columns["plant"] = plant_name(spec)
    return columns


def reference_controller_columns(config: StudyConfig) -> Columns:
    """The reference as a controller: ``oracle``, offline, its settings as the parameters."""
    return {
        "controller": REFERENCE_NAME,
        "filters": "none",
        "backend": REFERENCE_NAME,
        "controller_params": json.dumps(config.reference.model_dump(mode="json"), sort_keys=True),
        "loop_mode": OFFLINE,
        "information": OFFLINE_INFORMATION,
        "dt": config.dt,
    }


def information_columns(information: str) -> Columns:
    """What the row knew of the task: ``causal``, ``preview H s`` (the backend's) or offline."""
    return {"information": information}


def task_columns(descriptors: Mapping[str, Any], duration: float) -> Columns:
    """The built task: its generator's ``task.*`` descriptors and the episode duration [s]."""
    return {**{f"{TASK_PREFIX}{k}": v for k, v in descriptors.items()}, "duration": duration}


def metric_columns(
    metrics: Mapping[str, Any], ratios: Mapping[str, float] | None = None
) -> Columns:
    """Every metric of :data:`~otmm_qp.metrics.table.METRICS`, and the study's speed ratios.

    A metric ``metrics`` lacks is null; the ratios (``max_speed_ratio``, ``max_jump_ratio``
    [-], :func:`~otmm_qp.studies.criteria.speed_ratios`) only when given.
    """
    columns: Columns = {name: metrics.get(name) for name in _METRIC_NAMES}
    if ratios is not None:
        columns.update({name: ratios[name] for name in _RATIO_NAMES})
    return columns


def reference_columns(solved: Mapping[str, Any], seconds: float) -> Columns:
    """A solved reference's ``reference.*`` columns (``ReferenceResult.columns()``), timed [s]."""
    known = {name for name, _, _ in _REFERENCE}
    unknown = sorted(set(solved) - known)
    if unknown:
        raise ValueError(f"not reference columns: {', '.join(unknown)}")
    return {**solved, "reference.seconds": seconds}


def failed_reference_columns() -> Columns:
    """``reference.*`` of a task whose reference could not be computed at all."""
    columns: Columns = dict.fromkeys(REFERENCE_COLUMNS, math.nan)
    columns.update(
        {
            "reference.status": "failed",
            "reference.touches_position_limit": False,
            "reference.near_singular": False,
            "reference.achievable": False,
            "reference.converged": False,
            "reference.source": "none",
            "reference.certificate": "none",
            "reference.iterations": 0,
        }
    )
    return columns


def outcome_columns(status: str | None, error_message: str | None) -> Columns:
    """How the episode ended: ``ok``, ``stopped`` or ``error``, and the one-line reason."""
    return {"status": status, "error_message": error_message}


def limits_columns(kept: bool) -> Columns:
    """Whether the row's path kept the limits its task's reference keeps."""
    return {KEPT_REFERENCE_LIMITS: kept}


def success_columns(success: bool) -> Columns:
    """Success as judged when the row is stored (``load`` judges it again, see ``rows``)."""
    return {"success": success}


def series_columns(run: RunResult, key: str, stride: int) -> Columns:
    """One episode's time series, every ``stride``-th step: a ``timeseries`` part's columns.

    ``episode_key``, ``t`` [s], ``position_error`` [m], ``joint_speed`` (max_j |q̇_j| [rad/s]),
    ``sigma_min`` [-] and ``p`` [-], each a list of the same length.
    """
    picked = slice(None, None, stride)
    speed = np.max(np.abs(run.qdot), axis=1) if run.steps else np.zeros(0)
    return {
        "episode_key": [key] * len(run.t[picked]),
        "t": run.t[picked].tolist(),
        "position_error": run.position_error[picked].tolist(),
        "joint_speed": speed[picked].tolist(),
        "sigma_min": run.sigma_min[picked].tolist(),
        "p": run.p[picked].tolist(),
    }


def task_reference(oracle_row: Mapping[str, Any]) -> Columns:
    """The ``reference.*`` columns a task's other rows are judged with, from its oracle row.

    Its stored ``reference.*`` columns, with ``reference.max_error`` falling back to the
    row's ``max_error`` and ``reference.final_error`` its ``final_error`` [m]. One
    definition for the episode's stored ``success`` and the reader's judged one.
    """
    reference = {k: v for k, v in oracle_row.items() if k.startswith("reference.")}
    reference.setdefault("reference.max_error", oracle_row.get("max_error"))
    reference["reference.final_error"] = oracle_row.get("final_error")
    return reference


def judged_columns(
    causes: Sequence[str], kept: bool, relative: float | None, key: str | None = None
) -> Columns:
    """The columns :func:`otmm_qp.studies.load` judges on read (:data:`DERIVED_COLUMNS`).

    ``failure_causes`` (a tuple; a list once in Arrow), ``success`` (no cause), ``kept_limits``,
    ``oracle_relative_error`` [m]; ``episode_id`` too when the stored row lacks it (``key``).
    """
    columns: Columns = {
        "failure_causes": tuple(causes),
        "success": not causes,
        KEPT_LIMITS: kept,
        "oracle_relative_error": relative,
    }
    if key is not None:
        columns["episode_id"] = episode_id(key)
    return columns


def markdown_reference() -> str:
    """The column reference of ``docs/studies.md`` (Markdown table), from the declarations."""
    rows = [
        (f"`{column.name}`", str(column.type), column.doc)
        for column in (*EPISODE_COLUMNS, *DERIVED_COLUMNS)
    ]
    rows.append(
        (
            "`task.*`",
            "double, string or bool",
            "the generator's descriptors of the task (numbers as double)",
        )
    )
    return "\n".join(table_markdown(Table(("column", "type", "meaning"), rows)))


#: Markers around the generated table in ``docs/studies.md``.
DOC_BEGIN = "<!-- episode columns: generated by python -m otmm_qp.studies.columns -->"
DOC_END = "<!-- end of episode columns -->"


def main() -> int:
    """Print the column reference (between its markers) for ``docs/studies.md``."""
    print(f"{DOC_BEGIN}\n{markdown_reference()}\n{DOC_END}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
