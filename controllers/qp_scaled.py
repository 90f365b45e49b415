r"""Direction-preserving QP differential IK after Drake's ``DoDifferentialInverseKinematics``."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
import qpsolvers

from otmm_qp.backends.backend import (
    STATUS_BOUNDED,
    STATUS_INFEASIBLE,
    STATUS_OK,
    STATUS_STUCK,
    Backend,
    BackendOutput,
)
from otmm_qp.exceptions import InfeasibleProblem, ParameterError, SolverNotFound
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp_controllers.qp_problem import (
    BIG,
    VelocityBox,
    check_limit_parameters,
    per_joint,
    solve_with_qpsolvers,
    velocity_box,
)

POLICIES = ("raise", "hold")
#: qpsolvers backends that solve this near-LP reliably. ProxQP (proxsuite 0.8 through
#: qpsolvers 4.13) reports it primal infeasible for every tolerance tried, so it is excluded.
SCALED_SOLVERS = ("clarabel", "daqp", "osqp", "quadprog")


def build_scaled_qp(
    state: KinematicState,
    xdot: FloatArray,
    lower: FloatArray,
    upper: FloatArray,
    regularization: float,
    rcond: float = 1e-10,
) -> qpsolvers.Problem:
    r"""The direction-preserving QP in ``z = (q̇, α)`` (pure function).

    .. math::
        \min_{\dot q,\alpha}\ -\alpha + \tfrac{\varepsilon}{2}(\|\dot q\|^2 + \alpha^2)
        \quad\text{s.t.}\quad \sigma_i v_i^\top\dot q = \alpha\,u_i^\top\dot x_w\ (i \le r),
        \quad lb \le \dot q \le ub,\quad 0 \le \alpha \le \bar\alpha

    ``J_w q̇ = α ẋ_w`` is written in the shared SVD basis: its ``r`` rows with
    ``σ_i > rcond·σ_max`` (each normalised to unit norm), while the part of ``ẋ_w`` outside
    ``range(J_w)`` can only be met with ``α = 0``, so ``ᾱ = 0`` when that part exceeds
    ``1e-9‖ẋ_w‖`` and 1 otherwise. The equality rows are thus always linearly independent,
    even at an exactly singular ``J``.

    Args:
        state: Kinematic state (its SVD).
        xdot: ``ẋ_w``, shape ``(n,)``.
        lower: ``lb`` [rad/s], shape ``(nv,)``.
        upper: ``ub`` [rad/s], shape ``(nv,)``.
        regularization: ``ε > 0``.
        rcond: Relative rank threshold on the singular values.
    """
    sigma, U, Vt = state.sigma, state.U, state.Vt
    nv = Vt.shape[1]
    keep = sigma > max(rcond * (float(sigma[0]) if sigma.size else 0.0), np.finfo(float).tiny)
    coefficients = U[:, keep].T @ xdot  # u_iᵀẋ, (r,)
    outside = xdot - U[:, keep] @ coefficients  # part of ẋ outside range(J_w)
    alpha_max = 0.0 if np.linalg.norm(outside) > 1e-9 * np.linalg.norm(xdot) else 1.0
    rows = np.hstack([sigma[keep, None] * Vt[keep], -coefficients[:, None]])  # (r, nv+1)
    rows /= np.linalg.norm(rows, axis=1, keepdims=True)
    hessian = regularization * np.eye(nv + 1)
    linear = np.zeros(nv + 1)
    linear[-1] = -1.0
    lb = np.append(np.clip(lower, -BIG, BIG), 0.0)
    ub = np.append(np.clip(upper, -BIG, BIG), alpha_max)
    if rows.shape[0] == 0:
        return qpsolvers.Problem(hessian, linear, lb=lb, ub=ub)
    return qpsolvers.Problem(hessian, linear, A=rows, b=np.zeros(rows.shape[0]), lb=lb, ub=ub)


class ScaledQpBackend(Backend):
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
        solver: qpsolvers backend name, one of :data:`SCALED_SOLVERS` that is installed.
        limit_gain: ``g ∈ (0, 1]`` of the position-limit velocity bounds.
        acceleration_limit: ``a_max`` [rad/s²], scalar or shape ``(nv,)``; None: no limit.
        stuck_threshold: Status ``stuck`` when ``α`` is below it, in ``[0, 1]``.
        regularization: ``ε > 0``.
        infeasible_policy: ``raise`` (:class:`InfeasibleProblem`) or ``hold`` (zero speed
            clipped into the relaxed box, status ``infeasible``, ``α = 0``), used when the
            box is empty or no ``(q̇, α)`` exists (e.g. the box excludes ``q̇ = 0`` while
            ``J_w`` has no null space).

    Attributes:
        problem: :class:`qpsolvers.Problem` of the last step (built on access).
        alpha: ``α`` of the last step.
    """

    name = "qp_scaled"

    def __init__(
        self,
        solver: str = "daqp",
        limit_gain: float = 0.5,
        acceleration_limit: float | Sequence[float] | None = None,
        stuck_threshold: float = 0.1,
        regularization: float = 1e-6,
        infeasible_policy: Literal["raise", "hold"] = "raise",
    ) -> None:
        installed = [s for s in qpsolvers.available_solvers if s in SCALED_SOLVERS]
        if solver not in installed:
            raise SolverNotFound(solver, installed)
        check_limit_parameters(limit_gain, infeasible_policy, POLICIES, acceleration_limit)
        if not 0.0 <= stuck_threshold <= 1.0:
            raise ParameterError("stuck_threshold", f"must be in [0, 1], got {stuck_threshold}")
        if not (np.isfinite(regularization) and regularization > 0.0):
            raise ParameterError("regularization", f"must be > 0, got {regularization}")
        self.solver = solver
        self.limit_gain = float(limit_gain)
        self.acceleration_limit_param = acceleration_limit
        self.acceleration_limit: FloatArray | None = None
        self.stuck_threshold = float(stuck_threshold)
        self.regularization = float(regularization)
        self.infeasible_policy = infeasible_policy
        self.box: VelocityBox | None = None
        self.alpha = 1.0
        self._last: tuple[KinematicState, FloatArray] | None = None
        self._euclidean = True
        self._step = 0

    def bind(self, robot: Robot, dt: float) -> None:
        """Read the robot limits."""
        super().bind(robot, dt)
        self.acceleration_limit = per_joint(
            self.acceleration_limit_param, "acceleration_limit", robot.nv
        )
        self._euclidean = robot.nq == robot.nv
        self.reset()

    def reset(self) -> None:
        """Forget the step counter and the last problem."""
        self._step = 0
        self._last = None
        self.box = None

    @property
    def problem(self) -> qpsolvers.Problem | None:
        """The scaled QP of the last step."""
        if self._last is None or self.box is None:
            return None
        state, xdot = self._last
        return build_scaled_qp(state, xdot, self.box.lower, self.box.upper, self.regularization)

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Joint velocity [rad/s] realising ``α ẋ_w``; ``BackendOutput.scale = α``."""
        step = self._step
        self._step += 1
        robot = self.robot
        theta = state.q if self._euclidean else robot.joint_coordinates(state.q)
        box = velocity_box(
            theta, robot.position_limits, robot.velocity_limits, qdot_prev, self.dt,
            self.limit_gain, self.acceleration_limit,
        )  # fmt: skip
        self.box = box
        self._last = (state, xdot)
        if box.empty:
            return self._infeasible(step, box.conflict(robot.joint_names), box)
        lower, upper = box.lower, box.upper
        sigma = state.sigma
        keep = sigma > max(1e-10 * (float(sigma[0]) if sigma.size else 0.0), np.finfo(float).tiny)
        coefficients = state.U[:, keep].T @ xdot
        outside = xdot - state.U[:, keep] @ coefficients
        inside_range = np.linalg.norm(outside) <= 1e-9 * np.linalg.norm(xdot)
        if inside_range:
            candidate = state.Vt[keep].T @ (coefficients / sigma[keep])
            if np.all(candidate >= lower) and np.all(candidate <= upper):
                self.alpha = 1.0
                return BackendOutput(candidate, self._status(candidate, 1.0, box), scale=1.0)
        problem = build_scaled_qp(state, xdot, lower, upper, self.regularization)
        solution = solve_with_qpsolvers(problem, self.solver)
        if solution is None or not np.all(np.isfinite(solution)):
            detail = f"solver {self.solver!r} found no (q̇, α) with J q̇ = α ẋ inside the box"
            return self._infeasible(step, detail, box)
        alpha = float(np.clip(solution[-1], 0.0, 1.0))
        qdot = np.clip(solution[:-1], lower, upper)
        self.alpha = alpha
        return BackendOutput(qdot, self._status(qdot, alpha, box, 1e-7), scale=alpha)

    def _status(self, qdot: FloatArray, alpha: float, box: VelocityBox, tol: float = 1e-9) -> str:
        if alpha < self.stuck_threshold:
            return STATUS_STUCK
        lower, upper = box.lower, box.upper
        active = np.any(qdot - lower <= tol * (1.0 + np.abs(lower))) or np.any(
            upper - qdot <= tol * (1.0 + np.abs(upper))
        )
        return STATUS_BOUNDED if active else STATUS_OK

    def _infeasible(self, step: int, detail: str, box: VelocityBox) -> BackendOutput:
        if self.infeasible_policy == "raise":
            raise InfeasibleProblem(step, detail)
        lower, upper = box.relaxed()
        self.alpha = 0.0
        qdot = np.clip(np.zeros_like(lower), lower, upper)
        return BackendOutput(qdot, STATUS_INFEASIBLE, scale=0.0)
