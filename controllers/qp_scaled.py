r"""Direction-preserving QP differential IK after Drake's ``DoDifferentialInverseKinematics``."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
import numpy.typing as npt
import qpsolvers

from otmm_qp.backends.backend import BackendOutput, rank_cutoff
from otmm_qp.exceptions import ParameterError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.status import Status
from otmm_qp_controllers.qp_base import SOLVER_TOL, BoxQpBackend
from otmm_qp_controllers.qp_problem import BIG, QpProblem
from otmm_qp_controllers.qp_solvers import SESSIONS, Solution

BoolArray = npt.NDArray[np.bool_]
POLICIES = ("raise", "hold")
#: Solvers that solve this near-LP reliably. ProxQP (proxsuite 0.8, directly or through
#: qpsolvers 4.13) reports it primal infeasible for every tolerance tried, so it is excluded.
SCALED_SOLVERS = ("clarabel", "daqp", "osqp", "quadprog")

#: Part of ``ẋ_w`` outside ``range(J_w)``, relative to ``‖ẋ_w‖``, above which ``α = 0``.
RANGE_TOL = 1e-9


def range_split(state: KinematicState, xdot: FloatArray) -> tuple[BoolArray, bool]:
    """Mask of the kept singular values (:func:`rank_cutoff`) and whether ``ẋ_w ∈ range(J_w)``."""
    keep = state.sigma > rank_cutoff(state.sigma)
    coefficients = state.U[:, keep].T @ xdot
    outside = xdot - state.U[:, keep] @ coefficients
    return keep, bool(np.linalg.norm(outside) <= RANGE_TOL * np.linalg.norm(xdot))


def build_scaled_qp(
    state: KinematicState,
    xdot: FloatArray,
    bounds: FloatArray,
    regularization: float,
) -> QpProblem:
    r"""The direction-preserving QP in ``z = (q̇, α)`` (pure function).

    .. math::
        \min_{\dot q,\alpha}\ -\alpha + \tfrac{\varepsilon}{2}(\|\dot q\|^2 + \alpha^2)
        \quad\text{s.t.}\quad \sigma_i v_i^\top\dot q = \alpha\,u_i^\top\dot x_w\ (i \le r),
        \quad lb \le \dot q \le ub,\quad 0 \le \alpha \le \bar\alpha

    ``J_w q̇ = α ẋ_w`` is written in the shared SVD basis: its ``r`` rows with ``σ_i`` above
    the rank cutoff (each normalised to unit norm), while the part of ``ẋ_w`` outside
    ``range(J_w)`` can only be met with ``α = 0``, so ``ᾱ = 0`` when that part exceeds
    ``RANGE_TOL·‖ẋ_w‖`` and 1 otherwise. The equality rows are thus always linearly
    independent, even at an exactly singular ``J``.

    Args:
        state: Kinematic state (its SVD).
        xdot: ``ẋ_w``, shape ``(n,)``.
        bounds: ``[lb; ub]`` [rad/s], shape ``(2, nv)``.
        regularization: ``ε > 0``.
    """
    sigma, U, Vt = state.sigma, state.U, state.Vt
    nv = Vt.shape[1]
    keep, inside = range_split(state, xdot)
    coefficients = U[:, keep].T @ xdot  # u_iᵀẋ, (r,)
    rows = np.hstack([sigma[keep, None] * Vt[keep], -coefficients[:, None]])  # (r, nv+1)
    rows /= np.linalg.norm(rows, axis=1, keepdims=True)
    hessian = regularization * np.eye(nv + 1)
    linear = np.zeros(nv + 1)
    linear[-1] = -1.0
    lb = np.append(np.clip(bounds[0], -BIG, BIG), 0.0)
    ub = np.append(np.clip(bounds[1], -BIG, BIG), 1.0 if inside else 0.0)
    zeros = np.zeros(rows.shape[0])
    return QpProblem(hessian, linear, lb, ub, rows, zeros, zeros.copy())


class ScaledQpBackend(BoxQpBackend):
    r"""Realise the largest fraction ``α`` of the command without changing its direction.

    After Drake's ``DoDifferentialInverseKinematics``:

    .. math::
        \max_{\dot q,\ \alpha\in[0,1]}\ \alpha \quad\text{s.t.}\quad J_w\dot q = \alpha\dot x_w,
        \quad lb \le \dot q \le ub

    with the joint-velocity box of :func:`~otmm_qp_controllers.qp_problem.velocity_box`.
    Drake uses the linear cost ``−100α`` plus a null-space posture cost; here the QP of
    :func:`build_scaled_qp` is solved, ``−α + ε/2(‖q̇‖² + α²)``: the small ``ε`` makes the
    Hessian positive definite (quadprog, proxqp need it) and picks the minimum-norm ``q̇``;
    it lowers α below its maximum only when ``ε(1 + ‖q̇‖²/α²) > 1``.

    Near a singularity the equality forces ``α → 0`` for commands along the lost direction:
    that is a result (status ``stuck``), not a failure. When the pseudoinverse solution
    already lies in the box it is returned with ``α = 1`` without calling the solver.

    Args:
        solver: One of :data:`SCALED_SOLVERS` that is installed.
        limit_gain: ``g ∈ (0, 1]`` of the position-limit velocity bounds.
        acceleration_limit: ``a_max`` [rad/s²], scalar or shape ``(nv,)``; None: no limit.
        stuck_threshold: Status ``stuck`` when ``α`` is below it, in ``[0, 1]``.
        regularization: ``ε > 0``.
        infeasible_policy: ``raise`` (:class:`~otmm_qp.exceptions.InfeasibleProblem`) or
            ``hold`` (zero speed clipped into the relaxed box, ``α = 0``), used when the box
            is empty or no ``(q̇, α)`` exists (e.g. the box excludes ``q̇ = 0`` while ``J_w``
            has no null space).

    Attributes:
        alpha: ``α`` of the last step.
    """

    name = "qp_scaled"
    policies = POLICIES

    def __init__(
        self,
        solver: str = "daqp",
        limit_gain: float = 0.5,
        acceleration_limit: float | Sequence[float] | None = None,
        stuck_threshold: float = 0.1,
        regularization: float = 1e-6,
        infeasible_policy: Literal["raise", "hold"] = "raise",
    ) -> None:
        installed = set(qpsolvers.available_solvers) | set(SESSIONS)
        allowed = [s for s in SCALED_SOLVERS if s in installed]
        super().__init__(solver, limit_gain, acceleration_limit, infeasible_policy, allowed)
        if not 0.0 <= stuck_threshold <= 1.0:
            raise ParameterError("stuck_threshold", f"must be in [0, 1], got {stuck_threshold}")
        if not (np.isfinite(regularization) and regularization > 0.0):
            raise ParameterError("regularization", f"must be > 0, got {regularization}")
        self.stuck_threshold = float(stuck_threshold)
        self.regularization = float(regularization)
        self.alpha = 1.0
        self._last: tuple[KinematicState, FloatArray] | None = None

    def bind(self, robot: Robot, dt: float) -> None:
        """Read the robot limits."""
        super().bind(robot, dt)

    def reset(self) -> None:
        """Forget the step counter, the warm start and the last problem."""
        super().reset()
        self._last = None

    @property
    def problem(self) -> QpProblem | None:
        """The scaled QP of the last step (pure :func:`build_scaled_qp`)."""
        box = self.box
        if self._last is None or box is None:
            return None
        state, xdot = self._last
        bounds = np.array([box.lower, box.upper])
        return build_scaled_qp(state, xdot, bounds, self.regularization)

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Joint velocity [rad/s] realising ``α ẋ_w``; ``BackendOutput.scale = α``."""
        step, _, empty = self.begin_step(state, qdot_prev)
        self._last = (state, xdot)
        if empty:
            box = self.box
            assert box is not None  # noqa: S101 - begin_step ran
            return self._fail(step, box.conflict(self.robot.joint_names), None)
        keep, inside = range_split(state, xdot)
        if inside:
            sigma = state.sigma
            candidate = state.Vt[keep].T @ ((state.U[:, keep].T @ xdot) / sigma[keep])
            lower, upper = self.bounds
            if np.all(candidate >= lower) and np.all(candidate <= upper):
                self.alpha = 1.0
                return BackendOutput(candidate, self._status(candidate, 1.0, 1e-9), scale=1.0)
        problem = build_scaled_qp(state, xdot, self.bounds, self.regularization)
        self.session.load(problem)
        solution = self.session.solve()
        if solution.x is None or not np.all(np.isfinite(solution.x)):
            detail = f"solver {self.solver!r} found no (q̇, α) with J q̇ = α ẋ inside the box"
            return self._fail(step, detail, solution, problem)
        alpha = float(np.clip(solution.x[-1], 0.0, 1.0))
        qdot = np.clip(solution.x[:-1], self.bounds[0], self.bounds[1])
        self.alpha = alpha
        return BackendOutput(qdot, self._status(qdot, alpha, SOLVER_TOL), scale=alpha)

    def _status(self, qdot: FloatArray, alpha: float, tol: float) -> Status:
        return Status.STUCK if alpha < self.stuck_threshold else self.classify(qdot, tol)

    def _fail(
        self, step: int, detail: str, solution: Solution | None, problem: QpProblem | None = None
    ) -> BackendOutput:
        evidence = self.problem if problem is None else problem
        qdot, status = self.fallback(step, detail, evidence, solution)
        self.alpha = 0.0
        return BackendOutput(qdot, status, scale=0.0)
