"""The study's seam to the offline-optimal reference: one ``oracle`` row per task.

The row is an ordinary episode row (``controller = backend = "oracle"``, ``filters =
"none"``, ``loop_mode = "offline"``) whose metrics are :func:`compute_metrics` over the
reference's joint path, plus the task-level ``reference.*`` columns of the study contract
(other rows join them by ``task_id``). The row's columns are composed by the group builders of
:mod:`otmm_qp.studies.columns`; this module only solves.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from otmm_qp.metrics.metrics import MetricSettings, compute_metrics
from otmm_qp.reference import Candidate, ReferenceSettings, as_run, solve_reference
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.scenarios.generator import Task
from otmm_qp.studies.columns import (
    REFERENCE_NAME,
    episode_row,
    metric_columns,
    outcome_columns,
    reference_columns,
)
from otmm_qp.studies.schema import StudyConfig

__all__ = ["REFERENCE_NAME", "oracle_columns", "reference_settings"]


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
    return episode_row(
        metric_columns(metrics),
        reference_columns(result.columns(), result.seconds),
        outcome_columns("ok", result.message),
    )
