"""Drill-down: short episode ids, finding one stored episode and a run config that re-runs it.

Every episode row carries ``episode_id``, the first :data:`ID_LENGTH` hex digits of its
``episode_key`` (the SHA-256 of the episode's full spec), so the id is stable across runs and
executors. :func:`run_config` turns a stored row back into an ``otmm-qp run`` config whose
trajectory is the task itself (``{type: study_task, ...}``): running it reproduces the stored
metrics exactly (the wall-clock ``step_time_*`` aside).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from otmm_qp.exceptions import ConfigError, UnreachableTrajectory
from otmm_qp.runner.build import check_reachable
from otmm_qp.studies.keys import MIN_ID_LENGTH, episode_id
from otmm_qp.studies.schema import StudyConfig
from otmm_qp.studies.spec import controller_record, expand_controllers
from otmm_qp.studies.task import StudyTask

__all__ = ["episode_id", "find_episode", "run_config", "write_run_config"]


def find_episode(rows: list[dict[str, Any]], wanted: str, where: str) -> dict[str, Any]:
    """The one row whose ``episode_key`` starts with ``wanted``.

    Raises:
        ConfigError: ``--episode``: too short, not hexadecimal, unknown or ambiguous.
    """
    text = wanted.strip().lower()
    if len(text) < MIN_ID_LENGTH or any(c not in "0123456789abcdef" for c in text):
        raise ConfigError(
            "--episode",
            f"{wanted!r} is not an episode id (at least {MIN_ID_LENGTH} hex digits, "
            "as the report's 'id' column shows)",
        )
    found = [r for r in rows if str(r.get("episode_key", "")).startswith(text)]
    if not found:
        raise ConfigError("--episode", f"no episode {wanted!r} in {where}")
    if len(found) > 1:
        raise ConfigError(
            "--episode", f"{wanted!r} matches {len(found)} episodes in {where}; give more digits"
        )
    return found[0]


def run_config(config: StudyConfig, row: dict[str, Any]) -> dict[str, Any]:
    """An ``otmm-qp run`` config (as a dict) that re-runs the episode of ``row``.

    The experiment sets ``out_of_reach: true`` when the task leaves the workspace (a
    ``beyond_reach`` task, say), so the runner's workspace check lets it run.

    Raises:
        ConfigError: The row's robot, generator or controller is not in the study.
    """
    try:
        which = StudyTask.of_row(config, row)
    except ConfigError as error:
        raise ConfigError("--episode", error.message) from None
    robot_spec = config.robots[which.robot]
    controllers = {c.name: c for c in expand_controllers(config, "study.json")}
    if row.get("controller") not in controllers:
        raise ConfigError("--episode", f"controller {row.get('controller')!r} is not in study.json")
    robot = {"type": robot_spec.robot.type, **robot_spec.robot.params}
    entry = config.generators[which.generator]
    trajectory: dict[str, Any] = {
        "type": "study_task",
        "robot": robot,
        "generator": {"type": entry.type, **entry.params},
        "seed": which.seed,
    }
    if robot_spec.task_weight is not None:
        trajectory["task_weight"] = list(robot_spec.task_weight)
    built = which.build(config)
    task, duration = built.task, built.duration
    try:
        check_reachable(built.robot, task.trajectory, duration, "trajectory")
        out_of_reach = False
    except UnreachableTrajectory:
        out_of_reach = True
    identity = episode_id(str(row["episode_key"]))
    experiment: dict[str, Any] = {
        "name": f"episode-{identity}",
        "description": (
            f"study {config.name}, episode {identity}: robot {row['robot']}, "
            f"{row['generator']} task {row['task_index']}, controller {row['controller']}, "
            f"loop mode {row['loop_mode']}"
        ),
        "robot": robot,
        "q0": [float(v) for v in task.q0],
        "trajectory": trajectory,
        "duration": duration,
        "loop_modes": [row["loop_mode"]],
        "controllers": [controller_record(controllers[row["controller"]])],
    }
    if robot_spec.task_weight is not None:
        experiment["task_weight"] = list(robot_spec.task_weight)
    if out_of_reach:
        experiment["out_of_reach"] = True
    return {
        "name": f"{config.name}-episode-{identity}",
        "description": f"re-run of episode {identity} of study {config.name}",
        "dt": config.dt,
        "clik_gain": config.clik_gain,
        "metrics": config.metrics.model_dump(mode="json"),
        "experiments": [experiment],
    }


def write_run_config(path: Path, config: dict[str, Any]) -> None:
    """Write the run config as YAML (floats as ``repr``, so they read back bit for bit).

    Through :func:`otmm_qp.config.emit.write_config`, which states the schema ``version``.
    """
    from otmm_qp.config.emit import write_config

    write_config(path, config)
