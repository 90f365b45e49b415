"""What the reference yields per task, and its joint path as a run the metrics can read."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.reference.settings import LIMIT_TOUCH
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.simulation.recorder import task_position
from otmm_qp.simulation.run_result import RunResult
from otmm_qp.state import KinematicState
from otmm_qp.status import Status

ReferenceStatus = Literal["achievable", "unachievable", "undecided", "failed"]
#: The labels of a task, in report order.
LABELS: tuple[str, ...] = ("achievable", "unachievable", "undecided", "failed")

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
    "reference.upper",
    "reference.lower",
    "reference.position_error",
    "reference.position_lower",
    "reference.source",
    "reference.step",
    "reference.kkt_residual",
    "reference.converged",
    "reference.iterations",
    "reference.certificate",
)


@dataclass(frozen=True)
class Bracket:
    """Where the min-max lies and how the solve that bounds it from above ended.

    Attributes:
        upper: ``max_k m_k`` of the best path [tolerances] (no known path within the
            limits is better).
        lower: Certified lower bound of the min-max [tolerances]
            (:func:`~otmm_qp.reference.bound.lower_bound`).
        position_optimum: Smallest ``max_k ‖e_pos,k‖`` found within the limits [m] — the
            position-optimal reference (``reference.max_error``).
        position_lower: Certified lower bound of it [m].
        source: Which start the best path came from (``damped_ik``, ``joint_path``,
            ``least_squares``, ``epigraph``, ``perturbed`` or a controller's name).
        step: ``‖δ‖_∞`` of the epigraph solve's last QP [rad] (NaN: not run).
        kkt: Its KKT residual [tolerances] (NaN: not run).
        converged: It stopped on its convergence test.
        iterations: Its QPs.
        certificate: Which bound sets ``lower`` and at which sample, ``kind@k``
            (:attr:`~otmm_qp.reference.bound.LowerBound.certificate`; ``none``: 0).
    """

    upper: float
    lower: float
    position_optimum: float
    position_lower: float
    source: str = "damped_ik"
    step: float = math.nan
    kkt: float = math.nan
    converged: bool = False
    iterations: int = 0
    certificate: str = "none"


@dataclass
class ReferenceResult:
    """The reference of one task.

    Attributes:
        status: ``achievable`` (``path`` is within every limit and meets every tolerance: a
            certificate), ``unachievable`` (the certified lower bound exceeds a tolerance),
            ``undecided`` (neither), ``failed`` (a solver failure and no certificate;
            ``message`` says why, ``path`` is the best found).
        path: Best joint path found, shape ``(N, nv)`` [rad], ``q_0`` first; always within
            the position and step limits.
        times: Sample times [s], shape ``(N,)``.
        errors: Task errors along ``path``, shape ``(N, n)`` [m, rad].
        max_error: Largest position error of ``path`` [m] (``reference.position_error``;
            ``reference.max_error`` is the position optimum, ``bracket.position_optimum``).
        max_orientation_error: Largest orientation error [rad]; NaN for position tasks.
        max_joint_speed: Largest ``|q_{k+1} − q_k|/dt`` [rad/s].
        touches_position_limit: Some sample within ``LIMIT_TOUCH`` of a finite limit.
        sigma: σ_min of the weighted Jacobian along ``path``, shape ``(N,)``.
        weakest: Right singular vector of σ_min along ``path``, shape ``(N, nv)``.
        positions: End-effector position along ``path`` [m], shape ``(N, d)``.
        min_sigma: Smallest σ_min of the weighted Jacobian along the task's own path (the
            reference's start computed from the task alone, :func:`task_path`), so that it
            does not depend on which controllers' paths the study offered.
        near_singular: ``min_sigma < sigma_s``: the task passes near a singularity.
        warm_start_merit: ``max_k m_k`` of the warm start (see ``TrackingProblem.merits``).
        merit: ``max_k m_k`` of ``path`` (≤ ``warm_start_merit``; ≤ 1 when achievable).
        bracket: Upper and lower bounds, the position optimum and the solve's end.
        seconds: Wall time of the solve [s].
        message: Why the solve failed (or that the time budget ran out), else None.
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
    bracket: Bracket
    seconds: float = 0.0
    message: str | None = None

    @property
    def achievable(self) -> bool:
        """Whether a certificate was found (``status == "achievable"``)."""
        return self.status == "achievable"

    def columns(self) -> dict[str, Any]:
        """The contract's ``reference.*`` columns of this task."""
        bracket = self.bracket
        return {
            "reference.status": self.status,
            "reference.max_error": bracket.position_optimum,
            "reference.max_orientation_error": self.max_orientation_error,
            "reference.max_joint_speed": self.max_joint_speed,
            "reference.touches_position_limit": self.touches_position_limit,
            "reference.min_sigma": self.min_sigma,
            "reference.near_singular": self.near_singular,
            "reference.achievable": self.achievable,
            "reference.upper": bracket.upper,
            "reference.lower": bracket.lower,
            "reference.position_error": self.max_error,
            "reference.position_lower": bracket.position_lower,
            "reference.source": bracket.source,
            "reference.step": bracket.step,
            "reference.kkt_residual": bracket.kkt,
            "reference.converged": bracket.converged,
            "reference.iterations": bracket.iterations,
            "reference.certificate": bracket.certificate,
        }


def sigma_along(robot: Robot, path: FloatArray, weight: FloatArray | None) -> FloatArray:
    """σ_min of the weighted Jacobian at every sample of ``path`` ``(N, nv)``, shape ``(N,)``."""
    return np.array(
        [KinematicState.compute(robot, robot.configuration(q), weight).sigma_min for q in path]
    )


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
    errors: FloatArray | None = None,
    bracket: Bracket | None = None,
    task_path: FloatArray | None = None,
) -> ReferenceResult:
    """Evaluate a path within the limits: errors, speeds, limit contact and σ_min along it.

    Args:
        problem: The task.
        path: Joint path ``(N, nv)`` within the limits.
        weight: Task weight diagonal ``(n,)`` for σ_min (None: identity).
        status: The solve's outcome.
        warm_start_merit: ``max_k m_k`` of the warm start.
        message: Failure reason.
        errors: The path's task errors ``(N, n)`` when known (a controller's own record);
            else computed.
        bracket: The bounds (None: the path's own merit, lower bound 0).
        task_path: The task's own path ``(N, nv)`` on which ``min_sigma`` and
            ``near_singular`` are judged (None: ``path``).
    """
    robot = problem.robot
    errors = problem.errors(path) if errors is None else np.asarray(errors, dtype=float)
    linear = np.linalg.norm(errors[:, : problem.linear], axis=1)
    rotation = np.linalg.norm(errors[:, 3:], axis=1) if problem.pose else None
    speed = np.abs(velocities(path, problem.dt))
    states = [KinematicState.compute(robot, robot.configuration(q), weight) for q in path]
    sigma = np.array([s.sigma_min for s in states])
    finite_lo = np.isfinite(problem.lower)
    finite_hi = np.isfinite(problem.upper)
    near_lo = finite_lo & (path - problem.lower <= LIMIT_TOUCH)
    near_hi = finite_hi & (problem.upper - path <= LIMIT_TOUCH)
    own = sigma if task_path is None or task_path is path else sigma_along(robot, task_path, weight)
    min_sigma = float(np.min(own)) if own.size else math.nan
    merit = float(np.max(problem.merits(errors)))
    max_error = float(np.max(linear))
    if bracket is None:
        bracket = Bracket(merit, 0.0, max_error, 0.0)
    return ReferenceResult(
        status=status,
        path=path,
        times=problem.times.copy(),
        errors=errors,
        max_error=max_error,
        max_orientation_error=float(np.max(rotation)) if rotation is not None else math.nan,
        max_joint_speed=float(np.max(speed)) if speed.size else 0.0,
        touches_position_limit=bool(np.any(near_lo | near_hi)),
        sigma=sigma,
        weakest=np.array([s.weakest_joint_direction for s in states]),
        positions=np.array([task_position(np.asarray(s.x)) for s in states]),
        min_sigma=min_sigma,
        near_singular=bool(min_sigma < problem.settings.sigma_s),
        warm_start_merit=warm_start_merit,
        merit=merit,
        bracket=bracket,
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
