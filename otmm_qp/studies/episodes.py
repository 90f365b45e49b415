"""Run units of work (tasks × controllers × loop modes) and turn each episode into one row.

This module is what a worker process executes: it rebuilds robots and generators once per
process (cached by their spec) and never raises for one bad episode — a failure becomes a
row with ``status = "error"`` and the one-line message.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

from otmm_qp.config.schema import ControllerConfig
from otmm_qp.metrics.metrics import MetricSettings
from otmm_qp.reference import Candidate
from otmm_qp.reference.limits import PathLimits
from otmm_qp.simulation.run_result import RunResult
from otmm_qp.studies.columns import (
    Columns,
    controller_columns,
    episode_row,
    failed_reference_columns,
    identity_columns,
    information_columns,
    limits_columns,
    metric_columns,
    outcome_columns,
    reference_controller_columns,
    series_columns,
    success_columns,
    task_columns,
    task_reference,
)
from otmm_qp.studies.criteria import failure_causes, speed_ratios
from otmm_qp.studies.oracle import oracle_columns, reference_settings
from otmm_qp.studies.schema import StudyConfig, SuccessCriteria
from otmm_qp.studies.task import BuildCache, BuiltTask, PlannedEpisode, StudyTask, study_episode

#: Metrics that measure wall-clock time: they differ between runs and executors.
TIMING_METRICS = ("step_time_median_us", "step_time_p99_us", "reference.seconds")

_configs: dict[str, tuple[StudyConfig, list[ControllerConfig]]] = {}
_cache = BuildCache()


@dataclass(frozen=True)
class WorkUnit:
    """One task and the episodes still to run on it.

    Attributes:
        task: Which task (robot, generator entry, index, seed).
        episodes: The planned episodes still to run on it (each of ``task``; its reference
            one of them when it is not stored yet).
        time_series: Also return sampled time series.
        reference: The task's stored ``reference.*`` columns (``task_reference`` of its
            oracle row) when its reference episode is stored already, as sorted items.
    """

    task: StudyTask
    episodes: tuple[PlannedEpisode, ...]
    time_series: bool = False
    reference: tuple[tuple[str, Any], ...] | None = None

    def __post_init__(self) -> None:
        other = [e.key for e in self.episodes if e.task != self.task]
        if other:
            raise ValueError(f"episodes {', '.join(other)} are not of the unit's task")


@dataclass
class ChunkResult:
    """Episode rows of a chunk, sampled time series and the chunk's compute time [s].

    Each time series is one dict of columns.
    """

    rows: list[dict[str, Any]] = field(default_factory=list)
    series: list[dict[str, Any]] = field(default_factory=list)
    seconds: float = 0.0


def _study(payload: dict[str, Any]) -> tuple[StudyConfig, list[ControllerConfig]]:
    digest = str(payload["digest"])
    if digest not in _configs:
        config = StudyConfig.model_validate(payload["config"])
        controllers = [ControllerConfig.model_validate(c) for c in payload["controllers"]]
        _configs[digest] = (config, controllers)
    return _configs[digest]


def one_line(error: BaseException) -> str:
    """``Type: message`` on one line."""
    text = " ".join(str(error).split())
    return f"{type(error).__name__}: {text}" if text else type(error).__name__


def is_success(row: dict[str, Any], criteria: SuccessCriteria) -> bool:
    """Whether an episode row meets every criterion (:func:`criteria.failure_causes` is empty)."""
    return not failure_causes(row, criteria)


def _build(config: StudyConfig, unit: WorkUnit) -> tuple[BuiltTask | None, str | None]:
    """The unit's built task, or the generation error (one line)."""
    try:
        return unit.task.build(config, _cache), None
    except (Exception, SystemExit) as error:  # a failed task is a row, never a stopped study
        return None, f"task generation: {one_line(error)}"


def run_unit(payload: dict[str, Any], unit: WorkUnit, result: ChunkResult) -> None:
    """Generate the unit's task and run its episodes, appending rows (never raising).

    The controllers run first: every path of theirs that kept the limits is a candidate of
    the task's reference, solved next (so no known path beats it); then every controller
    row's stored ``success`` is judged with that reference, by the rule the report applies.
    Each controller row records whether its path kept the reference's limits
    (``within_reference_limits``, :class:`~otmm_qp.reference.limits.PathLimits`).
    A resumed task whose reference row is stored already is judged with the stored one
    (``unit.reference``). The reference row comes first in the rows, as before. Every row is
    composed of the column groups of :mod:`otmm_qp.studies.columns`.
    """
    config, controllers = _study(payload)
    built, task_error = _build(config, unit)
    identity = {e.key: identity_columns(config, unit.task, e.key) for e in unit.episodes}
    finished: list[Columns] = []  # controller rows, judged once the reference is known
    candidates: list[Candidate] = []
    limits = _path_limits(config, built)
    for episode in unit.episodes:
        if episode.is_reference:
            continue
        assert episode.controller is not None  # a controller episode (PlannedEpisode checks)
        spec = controllers[episode.controller]
        what = controller_columns(config, spec, episode.loop_mode)
        if built is None:
            failed = outcome_columns("error", task_error)
            finished.append(episode_row(identity[episode.key], what, failed))
            continue
        row, run = _controller_episode(config, spec, episode, built)
        row = episode_row(identity[episode.key], what, task_columns(*_task(built)), row)
        if run is not None:
            if unit.time_series:
                result.series.append(series_columns(run, episode.key, config.time_series.stride))
            if limits is not None:
                kept = row["status"] == "ok" and limits.keeps(run.q, run.error)
                row = episode_row(row, limits_columns(kept))
            if row["status"] == "ok":
                candidates.append(Candidate(spec.name, run.q, run.error, float(row["max_error"])))
        finished.append(row)
    reference = dict(unit.reference or {})
    oracle = next((e for e in unit.episodes if e.is_reference), None)
    if oracle is not None:
        head = episode_row(identity[oracle.key], reference_controller_columns(config))
        result.rows.append(_oracle_row(config, head, built, task_error, candidates))
        if built is not None:
            reference = task_reference(result.rows[-1])
    elif not reference and config.reference.enabled and built is not None:
        reference = task_reference(_reference_of(config, built, candidates))
    for row in finished:
        if row.get("status") == "error":
            result.rows.append(episode_row(row, success_columns(False)))
        else:
            success = is_success({**reference, **row}, config.success)
            result.rows.append(episode_row(row, success_columns(success)))


def _task(built: BuiltTask) -> tuple[dict[str, Any], float]:
    """The built task's descriptors and episode duration [s] (:func:`task_columns`)."""
    return dict(built.task.descriptors), built.duration


def _path_limits(config: StudyConfig, built: BuiltTask | None) -> PathLimits | None:
    """The limits the task's reference keeps (None without a reference or a task)."""
    if built is None or not config.reference.enabled:
        return None
    settings = reference_settings(config)
    return PathLimits.of(built.robot, settings, built.task.q0, config.dt, built.duration)


def _controller_episode(
    config: StudyConfig, spec: ControllerConfig, episode: PlannedEpisode, built: BuiltTask
) -> tuple[Columns, RunResult | None]:
    """Run one controller episode: its information, metric and outcome columns, and its run.

    On an error (stored in the row; plugins are untrusted) the run is None and the columns
    are the outcome (``status = "error"``, ``success`` false), after the backend's
    ``information`` when the controller was built.
    """
    from otmm_qp.runner.build import build_controller
    from otmm_qp.runner.episode import run_episode
    from otmm_qp.runner.plant_stage import build_stage

    settings = MetricSettings(**config.metrics.model_dump())
    information: Columns = {}
    try:
        made = build_controller(spec, f"controllers.{episode.controller}", settings.blow_up_speed)
        information = information_columns(made.backend.information)  # causal, or preview H s
        stage = build_stage(spec)
        record = run_episode(study_episode(config, built, episode.loop_mode), made, settings, stage)
    except (Exception, SystemExit) as error:  # recorded in the row; plugins are untrusted
        return episode_row(information, outcome_columns("error", one_line(error))), None
    run = record.result
    status = "ok" if run.error_message is None else "stopped"
    columns = episode_row(
        information,
        metric_columns(record.metrics, speed_ratios(run)),
        outcome_columns(status, run.error_message),
    )
    return columns, run


def _reference_of(config: StudyConfig, built: BuiltTask, candidates: list[Candidate]) -> Columns:
    """The task's solved reference: metrics, ``reference.*`` and outcome columns (never raising).

    An unexpected solver error is a ``failed`` reference whose ``status`` is null and whose
    ``error_message`` says why.
    """
    try:
        return oracle_columns(
            config, built.robot, built.weight, built.task, built.duration, candidates
        )
    except Exception as error:  # noqa: BLE001 - a failed reference is a row, never a crash
        failed = outcome_columns(None, f"reference: {one_line(error)}")
        return episode_row(failed_reference_columns(), failed)


def _oracle_row(
    config: StudyConfig,
    head: Columns,
    built: BuiltTask | None,
    task_error: str | None,
    candidates: list[Candidate],
) -> Columns:
    """The task's reference row after its identity and controller columns ``head``.

    Never raising: a task that could not be generated is an ``error`` row, an unexpected
    solver error a ``failed`` reference (``status`` null); both have ``success`` false.
    """
    if built is None:
        failed = outcome_columns("error", task_error)
        return episode_row(head, failed_reference_columns(), failed, success_columns(False))
    row = episode_row(head, task_columns(*_task(built)), _reference_of(config, built, candidates))
    success = row["status"] == "ok" and is_success(row, config.success)
    return episode_row(row, success_columns(success))


def run_chunk(payload: dict[str, Any], units: list[WorkUnit]) -> ChunkResult:
    """Run every unit of a chunk (the function a Dask worker executes)."""
    tic = time.perf_counter()
    result = ChunkResult()
    for unit in units:
        run_unit(payload, unit, result)
    result.seconds = time.perf_counter() - tic
    return result
