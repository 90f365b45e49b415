r"""The offline-optimal reference of one task: warm start, least squares, min-max refinement.

The solver sees the whole desired path ``x_d(t_k)``, ``k = 0..N−1``, and looks for

.. math::
    \min_{q_1..q_{N-1}} \max_k m_k(q_k) \quad\text{s.t.}\quad l \le q_k \le u,\quad
    |q_k - q_{k-1}| \le v_{max}\,dt,\quad q_0 \text{ given},

``m_k = max(‖e_pos,k‖/tol_pos, ‖e_rot,k‖/tol_rot)``. Three phases, each keeping the path
within every limit:

1. **Warm start**: per-sample damped IK, rate-limited and clipped
   (:func:`~otmm_qp.reference.warm_start.damped_ik_path`), or the trajectory's own joint
   path when it has one and it is better
   (:func:`~otmm_qp.reference.warm_start.joint_path_start`).
2. **Least squares**: trust-region Newton over the stacked ``½‖S e_k‖²`` with sequential
   QPs (:class:`~otmm_qp.reference.sqp.SequentialQP`), until it converges or every error
   is below ``SETTLE`` = 1 % of its tolerance. Where the limits do not bind, the
   samples decouple and this is each sample's own best, so also the min-max.
3. **Min-max** (only if (2) misses a tolerance): Lawson re-weighting
   ``ω_k ← ω_k m_k / mean(ω m)``, a few Newton steps per round, which moves the
   least-squares solution toward the min-max one where the speed limits couple samples.

The path with the smallest ``max_k m_k`` over all phases is returned, so the result is never
worse than the warm start. ``max_k m_k ≤ 1`` is a certificate (a concrete path, checked with
the true forward kinematics); otherwise the returned error is an upper bound on the
achievable one — a local method, it cannot prove that no better path exists.
"""

from __future__ import annotations

import time

import numpy as np

from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.reference.projection import project_path
from otmm_qp.reference.result import ReferenceResult, ReferenceStatus, summarise
from otmm_qp.reference.settings import ReferenceSettings
from otmm_qp.reference.sqp import SequentialQP, SolverFailure, TimeBudgetExceeded
from otmm_qp.reference.warm_start import damped_ik_path, joint_path_start
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.trajectories.trajectory import Trajectory

#: Newton iterations per min-max round.
ROUND_ITERATIONS = 2
#: The least-squares phase stops once every error is below this fraction of its tolerance
#: (a certificate with margin; finer digits would not change any verdict).
SETTLE = 1e-2
#: Smallest Lawson weight (relative to the mean), so no sample is dropped for good.
WEIGHT_FLOOR = 1e-6


def solve_reference(
    robot: Robot,
    trajectory: Trajectory,
    q0: FloatArray,
    dt: float,
    duration: float,
    settings: ReferenceSettings | None = None,
    task_weight: FloatArray | None = None,
) -> tuple[ReferenceResult, TrackingProblem]:
    """Best joint path within the limits for a task (see the module docstring).

    Args:
        robot: The arm.
        trajectory: Desired motion.
        q0: Start joint coordinates ``(nv,)``, inside the position limits.
        dt: Sample period [s].
        duration: Horizon [s] (``max(1, round(duration/dt))`` samples, as a simulation).
        settings: Tolerances, speed cap and budget (defaults: :class:`ReferenceSettings`).
        task_weight: Task weight ``(n,)`` of the reported σ_min (None: identity).

    Returns:
        ``(result, problem)``. A solver failure or the time budget gives
        ``status = "failed"`` with the best path found so far; it never raises for them.

    Raises:
        NotWithinJointLimits: ``q0`` is outside the position limits (bad input).
        DimensionError: ``q0`` has the wrong length.
    """
    settings = settings or ReferenceSettings()
    tic = time.perf_counter()
    robot.check_start(q0)
    problem = TrackingProblem(robot, trajectory, q0, dt, duration, settings)
    deadline = tic + settings.time_budget
    warm = damped_ik_path(problem)
    warm_merit = float(np.max(problem.merits(problem.errors(warm))))
    given = joint_path_start(problem, trajectory)
    if given is not None:
        given_merit = float(np.max(problem.merits(problem.errors(given))))
        if given_merit < warm_merit:
            warm, warm_merit = given, given_merit
    best, best_merit = warm, warm_merit
    message: str | None = None
    if problem.samples > 1:
        try:
            best, best_merit = _optimise(problem, warm, warm_merit, deadline)
        except _Stopped as stop:
            best, best_merit, message = stop.best, stop.merit, stop.reason
    status: ReferenceStatus = "feasible" if best_merit <= 1.0 else "infeasible"
    if message is not None and status != "feasible":
        status = "failed"
    else:
        message = None
    result = summarise(problem, best, task_weight, status, warm_merit, message)
    result.seconds = time.perf_counter() - tic
    return result, problem


class _Stopped(Exception):
    """Carries the best path when a phase stops on a failure or the budget."""

    def __init__(self, best: FloatArray, merit: float, reason: str) -> None:
        self.best, self.merit, self.reason = best, merit, reason
        super().__init__(reason)


def _optimise(
    problem: TrackingProblem, warm: FloatArray, warm_merit: float, deadline: float
) -> tuple[FloatArray, float]:
    """Phases 2 and 3 from the warm start: the best path and its merit."""
    settings = problem.settings
    sqp = SequentialQP(problem)
    best, best_merit = warm, warm_merit
    weights = np.ones(problem.samples - 1)

    def keep(path: FloatArray) -> FloatArray:
        nonlocal best, best_merit
        merits = problem.merits(problem.errors(path))
        if float(np.max(merits)) < best_merit:
            best, best_merit = path, float(np.max(merits))
        return merits

    path = warm
    try:
        path = sqp.improve(path, weights, settings.iterations, deadline, settle=SETTLE)
        merits = keep(path)
        for _ in range(settings.minimax_rounds if best_merit > 1.0 else 0):
            weights = weights * np.maximum(merits[1:], WEIGHT_FLOOR)
            weights = np.maximum(weights / np.mean(weights), WEIGHT_FLOOR)
            path = sqp.improve(path, weights, ROUND_ITERATIONS, deadline)
            merits = keep(path)
            if best_merit <= 1.0:
                break
    except TimeBudgetExceeded:
        raise _Stopped(
            best, best_merit, f"time budget of {settings.time_budget:g} s exceeded"
        ) from None
    except SolverFailure as error:
        raise _Stopped(best, best_merit, f"solver failure: {error}") from None
    return project_path(best, problem.lower, problem.upper, problem.step), best_merit
