r"""QP differential inverse kinematics with joint limits (pink / mink style)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Literal

import numpy as np

from otmm_qp.backends.backend import BackendOutput
from otmm_qp.exceptions import ParameterError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.status import Status
from otmm_qp_controllers.qp_barrier import BarrierRow, SingularityBarrier
from otmm_qp_controllers.qp_base import SOLVER_TOL, BoxQpBackend
from otmm_qp_controllers.qp_problem import BIG, QpProblem, build_qp, clip_into_box, per_joint
from otmm_qp_controllers.qp_solvers import QpSession, available_solvers, make_session

InfeasiblePolicy = Literal["raise", "hold", "dls"]
POLICIES = ("raise", "hold", "dls")

__all__ = ["POLICIES", "InfeasiblePolicy", "QpBackend", "available_solvers"]


class QpBackend(BoxQpBackend):
    r"""Damped least squares under joint position, velocity and acceleration limits.

    .. math::
        \min_{\dot q}\ \tfrac12\|J_w\dot q - \dot x_w\|^2 + \tfrac12\mu\|\dot q\|^2
        + \tfrac12 w_p\|\dot q - g_p(\theta_{nom} - \theta)\|^2
        \quad\text{s.t.}\quad lb \le \dot q \le ub

    (:func:`~otmm_qp_controllers.qp_problem.build_qp`) with the box of
    :func:`~otmm_qp_controllers.qp_problem.velocity_box`. Without posture cost and with no
    bound active the solution is DLS with ``μ = λ²`` added to ``JJᵀ``; ``BackendOutput.damping``
    reports the damping factor ``λ = √μ`` [task units], as every DLS backend does.

    Fast path: the unconstrained minimiser is computed from the shared SVD,

    .. math::
        \dot q^* = V\,\mathrm{diag}\Big(\frac{1}{\sigma_i^2+\mu'}\Big)V^\top b
        + \frac{1}{\mu'}(I - VV^\top)b,\qquad b = J_w^\top\dot x_w + w_p\dot q_p,
        \ \mu' = \mu + w_p

    and the QP is solved only when ``q̇*`` leaves the box (convexity makes ``q̇*`` the QP
    optimum otherwise). A QP result is clipped into the box (removing solver tolerance) so a
    returned ``q̇`` never violates a bound. Infeasible steps follow ``infeasible_policy``
    (:class:`~otmm_qp_controllers.qp_base.BoxQpBackend`; ``dls`` clips ``q̇*``).

    Args:
        damping: ``μ = λ² > 0``, the weight of ``½‖q̇‖²`` [task units² / (rad/s)²].
        solver: ``daqp``, ``proxsuite``, ``osqp`` (persistent sessions, warm started) or
            another installed qpsolvers backend (``quadprog``, ``clarabel``, ``proxqp``:
            solved from scratch each step); ``direct_<name>`` are aliases.
        limit_gain: ``g ∈ (0, 1]`` of the position-limit velocity bounds.
        acceleration_limit: ``a_max`` [rad/s²], scalar or shape ``(nv,)``; None: no limit.
        posture_weight: ``w_p ≥ 0`` of the posture cost (0: none).
        posture_gain: ``g_p ≥ 0`` [1/s] of the posture velocity.
        q_nominal: ``θ_nom`` joint coordinates (nv,); the first state seen after
            :meth:`reset` when omitted.
        infeasible_policy: ``raise``, ``hold`` or ``dls``.
        fast_path: Skip the QP when the unconstrained minimiser is feasible.
        singularity_barrier: None, or ``{sigma_safe: σ_safe ≥ 0, gain: γ ∈ (0, 1]}``: the
            barrier row of :mod:`~otmm_qp_controllers.qp_barrier` (σ_min kept above σ_safe).

    Attributes:
        used_qp: Whether the last step called the QP solver.
        barrier_row: The :class:`~otmm_qp_controllers.qp_barrier.BarrierRow` the last step
            enforced, or None (barrier off, or the optimum without it satisfied it).
    """

    name = "qp"
    policies = POLICIES

    def __init__(
        self,
        damping: float = 1e-3,
        solver: str = "daqp",
        limit_gain: float = 0.5,
        acceleration_limit: float | Sequence[float] | None = None,
        posture_weight: float = 0.0,
        posture_gain: float = 1.0,
        q_nominal: Sequence[float] | None = None,
        infeasible_policy: InfeasiblePolicy = "raise",
        fast_path: bool = True,
        singularity_barrier: SingularityBarrier | Mapping[str, float] | None = None,
    ) -> None:
        if not (np.isfinite(damping) and damping > 0.0):
            raise ParameterError("damping", f"must be a finite number > 0, got {damping}")
        super().__init__(solver, limit_gain, acceleration_limit, infeasible_policy)
        for field, value in (("posture_weight", posture_weight), ("posture_gain", posture_gain)):
            if not (np.isfinite(value) and value >= 0.0):
                raise ParameterError(field, f"must be >= 0, got {value}")
        self.damping = float(damping)
        self.posture_weight = float(posture_weight)
        self.posture_gain = float(posture_gain)
        self.q_nominal_param = None if q_nominal is None else np.asarray(q_nominal, dtype=float)
        self.q_nominal: FloatArray | None = None
        self.fast_path = bool(fast_path)
        self.barrier = SingularityBarrier.from_option(singularity_barrier)
        self._barrier_session: QpSession | None = None if self.barrier is None else (
            make_session(solver)
        )  # fmt: skip
        self._factor = float(np.sqrt(self.damping))
        self.used_qp = False
        self.barrier_row: BarrierRow | None = None
        self._posture_reference: FloatArray | None = None
        self._last: tuple[FloatArray, FloatArray, FloatArray | None] | None = None

    def bind(self, robot: Robot, dt: float) -> None:
        """Read the limits; allocate the QP data written in place each step."""
        self.q_nominal = per_joint(self.q_nominal_param, "q_nominal", robot.nv)
        super().bind(robot, dt)
        # With finite speed limits every non-empty box lies within ±BIG: the box is then
        # written straight into the problem's lb/ub (no copy, no clipping per step).
        self._box_in_problem = bool(np.all(self.limits.speed <= BIG))
        self._data = QpProblem.allocate(robot.nv, box=self.bounds if self._box_in_problem else None)
        self._barrier_data = QpProblem.allocate(robot.nv, 1)

    def reset(self) -> None:
        """Forget warm starts, the step counter and a defaulted nominal posture."""
        super().reset()
        if self._barrier_session is not None:
            self._barrier_session.reset()
        self._last = None
        self.barrier_row = None
        self._posture_reference = self.q_nominal

    @property
    def problem(self) -> QpProblem | None:
        """The QP of the last step, rebuilt by the pure :func:`build_qp` (barrier row included)."""
        box = self.box
        if self._last is None or box is None:
            return None
        jacobian, xdot, posture = self._last
        bounds = np.array([box.lower, box.upper])
        rows = 0 if self.barrier_row is None else 1
        problem = build_qp(
            jacobian, xdot, self.damping, bounds, self.posture_weight, posture,
            out=QpProblem.allocate(jacobian.shape[1], rows),
        )  # fmt: skip
        if self.barrier_row is not None:
            problem.C[0], problem.l[0] = self.barrier_row.row, self.barrier_row.lower
        return problem

    def unconstrained(
        self, state: KinematicState, xdot: FloatArray, posture: FloatArray | None
    ) -> FloatArray:
        """Minimiser ``q̇*`` of the cost without bounds, from the shared SVD [rad/s]."""
        sigma, Vt = state.sigma, state.Vt
        if posture is None:
            gains = sigma / (sigma * sigma + self.damping)
            return np.asarray(((xdot @ state.U) * gains) @ Vt)
        mu = self.damping + self.posture_weight
        b = Vt.T @ (sigma * (state.U.T @ xdot)) + self.posture_weight * posture
        c = Vt @ b
        return np.asarray(Vt.T @ (c / (sigma * sigma + mu)) + (b - Vt.T @ c) / mu)

    def _posture(self, theta: FloatArray) -> FloatArray:
        """``q̇_p = g_p(θ_nom − θ)`` [rad/s], shape ``(nv,)`` (``θ_nom``: the first θ if unset)."""
        if self._posture_reference is None:
            self._posture_reference = np.array(theta, dtype=float)
        return self.posture_gain * (self._posture_reference - theta)

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Joint velocity [rad/s], shape ``(nv,)``, within the joint-velocity box."""
        step, theta, empty = self.begin_step(state, qdot_prev)
        posture = None if self.posture_weight <= 0.0 else self._posture(theta)
        self._last = (state.task_jacobian, xdot, posture)
        self.used_qp = False
        self.barrier_row = None
        if empty:
            box = self.box
            assert box is not None  # noqa: S101 - begin_step ran
            detail = box.conflict(self.robot.joint_names)
            preferred = self.unconstrained(state, xdot, posture)
            qdot, status = self.fallback(step, detail, self.problem, None, preferred)
            return BackendOutput(qdot, status, self._factor)
        qdot, status = self._solve_box(step, state, xdot, posture)
        if self.barrier is not None and status in (Status.OK, Status.BOUNDED):
            qdot, status = self._enforce_barrier(step, state, qdot, status)
        return BackendOutput(qdot, status, self._factor)

    def _solve_box(
        self,
        step: int,
        state: KinematicState,
        xdot: FloatArray,
        posture: FloatArray | None,
    ) -> tuple[FloatArray, Status]:
        """The optimum under the box: the fast path when it applies, else the QP."""
        if self.fast_path:
            candidate = self.unconstrained(state, xdot, posture)
            status = self.inside_status(candidate, 1e-9)  # None outside the box or for NaN
            if status is not None:
                return candidate, status
        bounds = None if self._box_in_problem else self.bounds  # None: already in _data
        data = build_qp(
            state.task_jacobian, xdot, self.damping, bounds, self.posture_weight, posture,
            out=self._data,
        )  # fmt: skip
        return self._solve(step, self.session, data, state, xdot, posture)

    def _solve(
        self,
        step: int,
        session: QpSession,
        data: QpProblem,
        state: KinematicState,
        xdot: FloatArray,
        posture: FloatArray | None,
    ) -> tuple[FloatArray, Status]:
        """Solve ``data`` in ``session``; clip into the box, or fall back on failure."""
        self.used_qp = True
        session.load(data)
        solution = session.solve()
        settled = None if solution.x is None else clip_into_box(solution.x, self.bounds, SOLVER_TOL)
        if settled is None:  # no solution, or a non-finite one
            detail = f"solver {self.solver!r} found no solution ({solution.detail})"
            preferred = self.unconstrained(state, xdot, posture)
            return self.fallback(step, detail, data.copy(), solution, preferred)
        qdot, active = settled
        return qdot, Status.BOUNDED if active else Status.OK

    def _enforce_barrier(
        self, step: int, state: KinematicState, qdot: FloatArray, status: Status
    ) -> tuple[FloatArray, Status]:
        """Keep ``qdot`` if it satisfies the barrier row, else re-solve with the row."""
        barrier, robot = self.barrier, self.robot
        assert barrier is not None and self._last is not None  # noqa: S101 - caller checked
        if state.sigma.size < state.task_dim:  # σ_min ≡ 0: no barrier can apply
            return qdot, status
        if barrier.predicted(robot, state, qdot, self.dt) >= barrier.required(state):
            return qdot, status
        data = self._barrier_data
        row = barrier.row(robot, state, self.dt, np.clip(self.bounds, -BIG, BIG))
        self.barrier_row = row
        data.C[0], data.l[0] = row.row, row.lower
        jacobian, xdot, posture = self._last
        build_qp(jacobian, xdot, self.damping, self.bounds, self.posture_weight, posture, data)
        session = self._barrier_session
        assert session is not None  # noqa: S101 - made with the barrier
        qdot, status = self._solve(step, session, data, state, xdot, posture)
        if status in (Status.OK, Status.BOUNDED):
            status = Status.RELAXED if row.slack > 0.0 else Status.BOUNDED
        return qdot, status
