"""What the reference yields per task, and its joint path as a run the metrics can read."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.reference.settings import LIMIT_TOUCH
from otmm_qp.robots.robot import FloatArray
from otmm_qp.simulation.recorder import task_position
from otmm_qp.simulation.run_result import RunResult
from otmm_qp.state import KinematicState
from otmm_qp.status import Status

ReferenceStatus = Literal["feasible", "infeasible", "failed"]

#: Task-level columns of the reference (the study contract), in order.
REFERENCE_COLUMNS: tuple[str, ...] = (
    "reference.status",
    "reference.max_error",
    "reference.max_orientation_error",
    "reference.max_joint_speed",
    "reference.touches_position_limit",
    "reference.min_sigma",
    "reference.near_singular",
    "reference.achievable",
)


@dataclass
class ReferenceResult:
    """The reference of one task.

    Attributes:
        status: ``feasible`` (``path`` is within every limit and meets every tolerance: a
            certificate), ``infeasible`` (the best path found does not), ``failed`` (solver
            failure or time budget; ``message`` says which, ``path`` is the best found).
        path: Best joint path found, shape ``(N, nv)`` [rad], ``q_0`` first; always within
            the position and step limits.
        times: Sample times [s], shape ``(N,)``.
        errors: Task errors along ``path``, shape ``(N, n)`` [m, rad].
        max_error: Largest position error [m].
        max_orientation_error: Largest orientation error [rad]; NaN for position tasks.
        max_joint_speed: Largest ``|q_{k+1} − q_k|/dt`` [rad/s].
        touches_position_limit: Some sample within ``LIMIT_TOUCH`` of a finite limit.
        sigma: σ_min of the weighted Jacobian along ``path``, shape ``(N,)``.
        weakest: Right singular vector of σ_min along ``path``, shape ``(N, nv)``.
        positions: End-effector position along ``path`` [m], shape ``(N, d)``.
        min_sigma: Smallest of ``sigma``.
        near_singular: ``min_sigma < sigma_s``.
        warm_start_merit: ``max_k m_k`` of the warm start (see ``TrackingProblem.merits``).
        merit: ``max_k m_k`` of ``path`` (≤ ``warm_start_merit``; ≤ 1 when feasible).
        iterations: Newton iterations run.
        seconds: Wall time of the solve [s].
        message: Why the solve failed, else None.
    """

    status: ReferenceStatus
    path: FloatArray
    times: FloatArray
    errors: FloatArray
    max_error: float
    max_orientation_error: float
    max_joint_speed: float
    touches_position_limit: bool
    sigma: FloatArray
    weakest: FloatArray
    positions: FloatArray
    min_sigma: float
    near_singular: bool
    warm_start_merit: float
    merit: float
    seconds: float = 0.0
    message: str | None = None

    @property
    def achievable(self) -> bool:
        """Whether a certificate was found (``status == "feasible"``)."""
        return self.status == "feasible"

    def columns(self) -> dict[str, Any]:
        """The contract's ``reference.*`` columns of this task."""
        return {
            "reference.status": self.status,
            "reference.max_error": self.max_error,
            "reference.max_orientation_error": self.max_orientation_error,
            "reference.max_joint_speed": self.max_joint_speed,
            "reference.touches_position_limit": self.touches_position_limit,
            "reference.min_sigma": self.min_sigma,
            "reference.near_singular": self.near_singular,
            "reference.achievable": self.achievable,
        }


def velocities(path: FloatArray, dt: float) -> FloatArray:
    r"""Joint velocities ``q̇_k = (q_{k+1} − q_k)/dt``, ``q̇_{N−1} = 0``, shape ``(N, nv)``."""
    qdot = np.zeros_like(path)
    qdot[:-1] = np.diff(path, axis=0) / dt
    return qdot


def summarise(
    problem: TrackingProblem,
    path: FloatArray,
    weight: FloatArray | None,
    status: ReferenceStatus,
    warm_start_merit: float,
    message: str | None = None,
) -> ReferenceResult:
    """Evaluate a (feasible) path: errors, speeds, limit contact and σ_min along it.

    Args:
        problem: The task.
        path: Joint path ``(N, nv)`` within the limits.
        weight: Task weight diagonal ``(n,)`` for σ_min (None: identity).
        status: The solve's outcome.
        warm_start_merit: ``max_k m_k`` of the warm start.
        message: Failure reason.
    """
    robot = problem.robot
    errors = problem.errors(path)
    linear = np.linalg.norm(errors[:, : problem.linear], axis=1)
    rotation = np.linalg.norm(errors[:, 3:], axis=1) if problem.pose else None
    speed = np.abs(velocities(path, problem.dt))
    states = [KinematicState.compute(robot, robot.configuration(q), weight) for q in path]
    sigma = np.array([s.sigma_min for s in states])
    finite_lo = np.isfinite(problem.lower)
    finite_hi = np.isfinite(problem.upper)
    near_lo = finite_lo & (path - problem.lower <= LIMIT_TOUCH)
    near_hi = finite_hi & (problem.upper - path <= LIMIT_TOUCH)
    min_sigma = float(np.min(sigma)) if sigma.size else math.nan
    return ReferenceResult(
        status=status,
        path=path,
        times=problem.times.copy(),
        errors=errors,
        max_error=float(np.max(linear)),
        max_orientation_error=float(np.max(rotation)) if rotation is not None else math.nan,
        max_joint_speed=float(np.max(speed)) if speed.size else 0.0,
        touches_position_limit=bool(np.any(near_lo | near_hi)),
        sigma=sigma,
        weakest=np.array([s.weakest_joint_direction for s in states]),
        positions=np.array([task_position(np.asarray(s.x)) for s in states]),
        min_sigma=min_sigma,
        near_singular=bool(min_sigma < problem.settings.sigma_s),
        warm_start_merit=warm_start_merit,
        merit=float(np.max(problem.merits(errors))),
        message=message,
    )


def as_run(result: ReferenceResult, problem: TrackingProblem) -> RunResult:
    """The reference path as a :class:`RunResult` (``loop_mode = "offline"``), for the metrics.

    ``q̇`` is the path's finite difference (held at zero on the last sample), ``status`` is
    ``ok`` on every sample and step times are zero.
    """
    robot = problem.robot
    qdot = velocities(result.path, problem.dt)
    count = result.path.shape[0]
    return RunResult(
        experiment="reference",
        controller="oracle",
        loop_mode="offline",
        dt=problem.dt,
        joint_names=robot.joint_names,
        task_kind=robot.task_kind,
        t=result.times.copy(),
        q=result.path.copy(),
        qdot=qdot,
        position=result.positions.copy(),
        position_desired=np.array([task_position(np.asarray(x)) for x in problem.targets]),
        error=result.errors.copy(),
        sigma_min=result.sigma.copy(),
        p=np.zeros(count),
        filter_active=np.zeros(count, dtype=bool),
        removed=np.zeros(count),
        damping=np.full(count, np.nan),
        scale=np.ones(count),
        weak_speed=np.abs(np.sum(result.weakest * qdot, axis=1)),
        status=np.array([Status.OK.value] * count, dtype=object),
        step_time=np.zeros(count),
        position_limits=robot.position_limits,
        velocity_limits=robot.velocity_limits,
        filters="none",
        backend="oracle",
    )
