"""The study's seam to the offline-optimal reference: one ``oracle`` row per task.

The row is an ordinary episode row (``controller = backend = "oracle"``, ``filters =
"none"``, ``loop_mode = "offline"``) whose metrics are :func:`compute_metrics` over the
reference's joint path, plus the task-level ``reference.*`` columns of the study contract
(other rows join them by ``task_id``).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from typing import Any

from otmm_qp.metrics.metrics import METRIC_NAMES, MetricSettings, compute_metrics
from otmm_qp.reference import (
    REFERENCE_COLUMNS,
    Candidate,
    ReferenceSettings,
    as_run,
    solve_reference,
)
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.scenarios.generator import Task
from otmm_qp.studies.schema import StudyConfig

#: The controller index of a task's reference episode (no controller of the study has it).
REFERENCE_INDEX = -1
#: The reference rows' ``controller`` and ``backend`` names (the data contract with the report).
REFERENCE_NAME = "oracle"
#: The loop mode of the reference's episode.
OFFLINE = "offline"


def task_reference(oracle_row: dict[str, Any]) -> dict[str, Any]:
    """The ``reference.*`` columns a task's other rows are judged with, from its oracle row.

    Its stored ``reference.*`` columns, with ``reference.max_error`` falling back to the
    row's ``max_error`` and ``reference.final_error`` its ``final_error`` [m]. One
    definition for the episode's stored ``success`` and the report's recomputed one.
    """
    reference = {k: v for k, v in oracle_row.items() if k.startswith("reference.")}
    reference.setdefault("reference.max_error", oracle_row.get("max_error"))
    reference["reference.final_error"] = oracle_row.get("final_error")
    return reference


def reference_settings(config: StudyConfig) -> ReferenceSettings:
    """Tolerances from ``success``, σ_S from ``metrics``, budget from ``reference``."""
    success, reference = config.success, config.reference
    return ReferenceSettings(
        position_tolerance=success.max_position_error,
        orientation_tolerance=success.max_orientation_error,
        speed_limit=success.max_joint_speed if reference.speed_bound == "criteria" else None,
        sigma_s=config.metrics.sigma_s,
        time_budget=reference.time_budget,
        iterations=reference.iterations,
        minimax_rounds=reference.minimax_rounds,
        polish_iterations=reference.polish_iterations,
        starts=reference.starts,
        perturbations=reference.perturbations,
    )


def oracle_fields(config: StudyConfig) -> dict[str, Any]:
    """The columns that name the reference as a controller."""
    return {
        "controller": REFERENCE_NAME,
        "filters": "none",
        "backend": REFERENCE_NAME,
        "controller_params": json.dumps(config.reference.model_dump(mode="json"), sort_keys=True),
        "loop_mode": OFFLINE,
    }


def failed_columns(message: str) -> dict[str, Any]:
    """``reference.*`` of a task whose reference could not be computed at all."""
    columns: dict[str, Any] = dict.fromkeys(REFERENCE_COLUMNS, math.nan)
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
            "error_message": message,
        }
    )
    return columns


def oracle_columns(
    config: StudyConfig,
    robot: Robot,
    weight: FloatArray | None,
    task: Task,
    duration: float,
    candidates: Sequence[Candidate] = (),
) -> dict[str, Any]:
    """Solve the task's reference; its metrics, ``reference.*`` columns and status.

    ``candidates`` are the task's controller paths (those that kept every limit count). A
    solver failure is ``reference.status = "failed"`` (``error_message`` says why) with the
    metrics of the best path found; it never raises for it.
    """
    result, problem = solve_reference(
        robot,
        task.trajectory,
        task.q0,
        config.dt,
        duration,
        reference_settings(config),
        weight,
        candidates,
    )
    metrics = compute_metrics(
        as_run(result, problem), MetricSettings(**config.metrics.model_dump())
    )
    columns: dict[str, Any] = {name: metrics.get(name) for name in METRIC_NAMES}
    columns.update(result.columns())
    columns["reference.seconds"] = result.seconds
    columns["status"] = "ok"
    columns["error_message"] = result.message
    return columns
