"""Run units of work (tasks × controllers × loop modes) and turn each episode into one row.

This module is what a worker process executes: it rebuilds robots and generators once per
process (cached by their spec) and never raises for one bad episode — a failure becomes a
row with ``status = "error"`` and the one-line message.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from otmm_qp import registry
from otmm_qp.config.schema import ControllerConfig
from otmm_qp.metrics.metrics import METRIC_NAMES, MetricSettings
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.scenarios.generator import Task, TaskGenerator
from otmm_qp.simulation.episode import Episode, Loop
from otmm_qp.simulation.run_result import RunResult
from otmm_qp.studies.criteria import failure_causes, speed_ratios
from otmm_qp.studies.drilldown import episode_id
from otmm_qp.studies.oracle import (
    REFERENCE_INDEX,
    failed_columns,
    oracle_columns,
    oracle_fields,
    task_reference,
)
from otmm_qp.studies.schema import StudyConfig, SuccessCriteria
from otmm_qp.studies.spec import plant_name
from otmm_qp.studies.task_ids import entry_label, task_id

#: The ``information`` column of the reference rows (the row's backend's
#: :attr:`~otmm_qp.backends.backend.Backend.information` for every other row).
OFFLINE_INFORMATION = "offline"
#: Metrics that measure wall-clock time: they differ between runs and executors.
TIMING_METRICS = ("step_time_median_us", "step_time_p99_us", "reference.seconds")

_configs: dict[str, tuple[StudyConfig, list[ControllerConfig]]] = {}
_robots: dict[str, Robot] = {}
_generators: dict[str, TaskGenerator] = {}


@dataclass(frozen=True)
class WorkUnit:
    """One task and the episodes still to run on it.

    Attributes:
        robot: Robot index in the study.
        generator: Generator index.
        task_index: Index of the task within its generator.
        seed: Task seed.
        episodes: ``(key, controller index, loop mode)`` of each episode to run.
        time_series: Also return sampled time series.
    """

    robot: int
    generator: int
    task_index: int
    seed: int
    episodes: tuple[tuple[str, int, str], ...]
    time_series: bool = False


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


def _robot(config: StudyConfig, index: int) -> Robot:
    spec = config.robots[index]
    key = json.dumps(spec.robot.model_dump(mode="json"), sort_keys=True)
    if key not in _robots:
        _robots[key] = registry.create(
            registry.ROBOTS, spec.robot.type, spec.robot.params, f"robots.{index}.robot"
        )
    return _robots[key]


def _generator(config: StudyConfig, index: int) -> TaskGenerator:
    spec = config.generators[index]
    key = json.dumps({"type": spec.type, **spec.params}, sort_keys=True, default=str)
    if key not in _generators:
        _generators[key] = registry.create(
            registry.TASK_GENERATORS, spec.type, spec.params, f"generators.{index}"
        )
    return _generators[key]


def one_line(error: BaseException) -> str:
    """``Type: message`` on one line."""
    text = " ".join(str(error).split())
    return f"{type(error).__name__}: {text}" if text else type(error).__name__


def is_success(row: dict[str, Any], criteria: SuccessCriteria) -> bool:
    """Whether an episode row meets every criterion (:func:`criteria.failure_causes` is empty)."""
    return not failure_causes(row, criteria)


def _base_row(
    config: StudyConfig,
    controllers: list[ControllerConfig],
    unit: WorkUnit,
    key: str,
    controller: int,
    mode: str,
) -> dict[str, Any]:
    gen = config.generators[unit.generator]
    row: dict[str, Any] = {
        "study": config.name,
        "episode_key": key,
        "task_id": task_id(config, unit.robot, unit.generator, unit.task_index),
        "episode_id": episode_id(key),
        "robot": config.robots[unit.robot].name,
        "generator": gen.type,
        "generator_entry": entry_label(config, unit.generator),
        "generator_params": json.dumps(gen.params, sort_keys=True, default=str),
        "task_index": unit.task_index,
        "task_seed": unit.seed,
    }
    if controller == REFERENCE_INDEX:
        row.update(oracle_fields(config))
    else:
        spec = controllers[controller]
        params = {
            **{f"{f.type}.{k}": v for f in spec.filters for k, v in f.params.items()},
            **{f"{spec.backend.type}.{k}": v for k, v in spec.backend.params.items()},
        }
        row.update(
            {
                "controller": spec.name,
                "filters": "+".join(f.type for f in spec.filters) or "none",
                "backend": spec.backend.type,
                "controller_params": json.dumps(params, sort_keys=True, default=str),
                "loop_mode": mode,
                **({"plant": plant_name(spec)} if config.plants is not None else {}),
            }
        )
    row["dt"] = config.dt
    return row


def _series(run: RunResult, key: str, stride: int) -> dict[str, Any]:
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


def _generate_task(
    config: StudyConfig, unit: WorkUnit
) -> tuple[Robot | None, FloatArray | None, Task | None, str | None]:
    """The unit's robot, task weight and task, or (what was built and) the generation error."""
    task: Task | None = None
    task_error: str | None = None
    robot: Robot | None = None
    weight = None
    try:
        robot = _robot(config, unit.robot)
        spec = config.robots[unit.robot]
        weight = np.asarray(spec.task_weight, dtype=float) if spec.task_weight else None
        task = _generator(config, unit.generator).generate(robot, unit.seed, weight)
    except (Exception, SystemExit) as error:  # a failed task is a row, never a stopped study
        task_error = f"task generation: {one_line(error)}"
    return robot, weight, task, task_error


def _episode_duration(config: StudyConfig, task: Task) -> float:
    """The task's duration plus the study's extra time, capped at its maximum [s]."""
    duration = task.duration + config.duration.extra
    if config.duration.max is not None:
        duration = min(duration, config.duration.max)
    return duration


def study_episode(
    config: StudyConfig, robot: Robot, task: Task, weight: FloatArray | None, mode: str
) -> Episode:
    """The :class:`Episode` of one task in one loop mode (checked like every run's).

    Raises:
        OtmmError: The task's start is outside the joint limits, or a value out of range
            (e.g. more than ``max_steps`` steps).
    """
    return Episode(
        robot,
        task.trajectory,
        robot.check_start(task.q0),
        config.dt,
        _episode_duration(config, task),
        Loop(mode, config.clik_gain),  # type: ignore[arg-type]
        weight,
        config.name,
        config.max_steps,
    )


def run_unit(payload: dict[str, Any], unit: WorkUnit, result: ChunkResult) -> None:
    """Generate the unit's task and run its episodes, appending rows (never raising)."""
    from otmm_qp.runner.build import build_controller
    from otmm_qp.runner.episode import run_episode
    from otmm_qp.runner.plant_stage import build_stage

    config, controllers = _study(payload)
    settings = MetricSettings(**config.metrics.model_dump())
    robot, weight, task, task_error = _generate_task(config, unit)
    # The reference first: every controller row's stored ``success`` is judged with it, by
    # the rule the report applies (graceful criteria on the tasks it cannot meet).
    episodes = sorted(unit.episodes, key=lambda episode: episode[1] != REFERENCE_INDEX)
    reference: dict[str, Any] = {}
    if (
        config.reference.enabled
        and task is not None
        and robot is not None
        and all(controller != REFERENCE_INDEX for _, controller, _ in episodes)
    ):  # the task's reference row is stored already (a resumed study): solve it again
        base = {"duration": _episode_duration(config, task)}
        reference = task_reference(_oracle_row(config, base, robot, weight, task, base["duration"]))
    for key, controller, mode in episodes:
        row = _base_row(config, controllers, unit, key, controller, mode)
        if task is not None:
            row.update({f"task.{k}": v for k, v in task.descriptors.items()})
        if task is None or robot is None:
            row.update(status="error", error_message=task_error, success=False)
            if controller == REFERENCE_INDEX:
                row.update(failed_columns(str(task_error)), status="error")
            result.rows.append(row)
            continue
        duration = _episode_duration(config, task)
        row["duration"] = duration
        if controller == REFERENCE_INDEX:
            oracle = _oracle_row(config, row, robot, weight, task, duration)
            oracle["information"] = OFFLINE_INFORMATION  # the whole path, solved offline
            reference = task_reference(oracle)
            result.rows.append(oracle)
            continue
        try:
            built = build_controller(
                controllers[controller], f"controllers.{controller}", settings.blow_up_speed
            )
            row["information"] = built.backend.information  # causal, or preview H s
            stage = build_stage(controllers[controller])
            episode = study_episode(config, robot, task, weight, mode)
            record = run_episode(episode, built, settings, stage)
        except (Exception, SystemExit) as error:  # recorded in the row; plugins are untrusted
            row.update(status="error", error_message=one_line(error), success=False)
            result.rows.append(row)
            continue
        run, metrics = record.result, record.metrics
        row.update({name: metrics.get(name) for name in METRIC_NAMES})
        row.update(speed_ratios(run))
        row["status"] = "ok" if run.error_message is None else "stopped"
        row["error_message"] = run.error_message
        row["success"] = is_success({**reference, **row}, config.success)
        result.rows.append(row)
        if unit.time_series:
            result.series.append(_series(run, key, config.time_series.stride))


def _oracle_row(
    config: StudyConfig,
    row: dict[str, Any],
    robot: Robot,
    weight: FloatArray | None,
    task: Task,
    duration: float,
) -> dict[str, Any]:
    """The task's reference row (never raising: an unexpected error is a ``failed`` row)."""
    try:
        row.update(oracle_columns(config, robot, weight, task, duration))
    except Exception as error:  # noqa: BLE001 - a failed reference is a row, never a crash
        row.update(failed_columns(f"reference: {one_line(error)}"), success=False)
        return row
    row["success"] = is_success(row, config.success)
    return row


def run_chunk(payload: dict[str, Any], units: list[WorkUnit]) -> ChunkResult:
    """Run every unit of a chunk (the function a Dask worker executes)."""
    tic = time.perf_counter()
    result = ChunkResult()
    for unit in units:
        run_unit(payload, unit, result)
    result.seconds = time.perf_counter() - tic
    return result
