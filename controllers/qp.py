r"""QP differential inverse kinematics with joint limits (pink / mink style)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
import qpsolvers

from otmm_qp.backends.backend import (
    STATUS_BOUNDED,
    STATUS_INFEASIBLE,
    STATUS_OK,
    Backend,
    BackendOutput,
)
from otmm_qp.exceptions import (
    InfeasibleProblem,
    ParameterError,
    SolverNotFound,
)
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp_controllers.qp_problem import (
    BIG,
    BoxBuffers,
    VelocityBox,
    build_qp,
    check_limit_parameters,
    per_joint,
    solve_with_qpsolvers,
    velocity_box,
)

InfeasiblePolicy = Literal["raise", "hold", "dls"]
POLICIES = ("raise", "hold", "dls")
#: Persistent, warm-started solver paths built once in :meth:`QpBackend.bind`.
DIRECT_SOLVERS = ("direct_daqp", "direct_osqp", "direct_proxsuite")


def available_solvers() -> list[str]:
    """Names accepted by ``solver``: installed qpsolvers backends plus the direct paths."""
    names = list(qpsolvers.available_solvers)
    if "daqp" in names:
        names.append("direct_daqp")
    if "proxqp" in names:
        names.append("direct_proxsuite")
    if "osqp" in names:
        names.append("direct_osqp")
    return sorted(names)


class QpBackend(Backend):
    r"""Damped least squares under joint position, velocity and acceleration limits.

    .. math::
        \min_{\dot q}\ \tfrac12\|J_w\dot q - \dot x_w\|^2 + \tfrac12\lambda\|\dot q\|^2
        + \tfrac12 w_p\|\dot q - g_p(\theta_{nom} - \theta)\|^2
        \quad\text{s.t.}\quad lb \le \dot q \le ub

    with the box ``[lb, ub]`` of :func:`~otmm_qp_controllers.qp_problem.velocity_box`
    (position limits with gain ``g``, speed limits, optional acceleration limits). Without
    posture cost and with no bound active the solution is DLS with ``μ = λ`` added to
    ``JJᵀ`` (a damping *factor* ``√λ`` in :class:`DampedLeastSquaresBackend` terms).

    Fast path: the unconstrained minimiser is computed from the shared SVD,

    .. math::
        \dot q^* = V\,\mathrm{diag}\Big(\frac{1}{\sigma_i^2+\mu}\Big)V^\top b
        + \frac{1}{\mu}(I - VV^\top)b,\qquad b = J_w^\top\dot x_w + w_p\dot q_p,
        \ \mu = \lambda + w_p

    and the QP is solved only when ``q̇*`` leaves the box (convexity makes ``q̇*`` the QP
    optimum otherwise). A QP result is clipped into the box (removing solver tolerance) so a
    returned ``q̇`` never violates a bound.

    Infeasible steps (empty box) follow ``infeasible_policy``:

    * ``raise``: :class:`~otmm_qp.exceptions.InfeasibleProblem` naming the joint and boxes;
    * ``hold``: zero velocity clipped into the *relaxed* box (limits honoured by priority
      velocity > position > acceleration, see :meth:`VelocityBox.relaxed`);
    * ``dls``: the unconstrained damped solution ``q̇*`` clipped into the relaxed box.

    Both non-raising policies report status ``infeasible``; so does a solver failure.

    Args:
        damping: ``λ > 0`` [task units² / (rad/s)²].
        solver: A qpsolvers name (``proxqp``, ``osqp``, ``daqp``, ``quadprog``,
            ``clarabel``) or ``direct_daqp`` / ``direct_proxsuite`` / ``direct_osqp``
            (persistent solver built once in :meth:`bind`, updated in place and warm started
            every step: daqp from the previous active set, proxsuite and osqp from the
            previous primal-dual solution).
        limit_gain: ``g ∈ (0, 1]`` of the position-limit velocity bounds.
        acceleration_limit: ``a_max`` [rad/s²], scalar or shape ``(nv,)``; None: no limit.
        posture_weight: ``w_p ≥ 0`` of the posture cost (0: none).
        posture_gain: ``g_p ≥ 0`` [1/s] of the posture velocity.
        q_nominal: ``θ_nom`` joint coordinates (nv,); the first state seen after
            :meth:`reset` when omitted.
        infeasible_policy: ``raise``, ``hold`` or ``dls``.
        fast_path: Skip the QP when the unconstrained minimiser is feasible.

    Attributes:
        problem: The :class:`qpsolvers.Problem` of the last step (built on access, also on
            fast-path steps), or None before the first step.
        box: The :class:`VelocityBox` of the last step (built on access from the step's
            inputs; the step itself only evaluates ``lb``/``ub`` into preallocated arrays).
        used_qp: Whether the last step called the QP solver.
    """

    name = "qp"

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
    ) -> None:
        if not (np.isfinite(damping) and damping > 0.0):
            raise ParameterError("damping", f"must be a finite number > 0, got {damping}")
        installed = available_solvers()
        if solver not in installed:
            raise SolverNotFound(solver, installed)
        check_limit_parameters(limit_gain, infeasible_policy, POLICIES, acceleration_limit)
        if not (np.isfinite(posture_weight) and posture_weight >= 0.0):
            raise ParameterError("posture_weight", f"must be >= 0, got {posture_weight}")
        if not (np.isfinite(posture_gain) and posture_gain >= 0.0):
            raise ParameterError("posture_gain", f"must be >= 0 [1/s], got {posture_gain}")
        self.damping = float(damping)
        self.solver = solver
        self.limit_gain = float(limit_gain)
        self.acceleration_limit_param = acceleration_limit
        self.posture_weight = float(posture_weight)
        self.posture_gain = float(posture_gain)
        self.q_nominal_param = None if q_nominal is None else np.asarray(q_nominal, dtype=float)
        self.infeasible_policy = infeasible_policy
        self.fast_path = bool(fast_path)
        self._box: VelocityBox | None = None
        self._box_inputs: tuple[FloatArray, FloatArray] | None = None
        self.used_qp = False
        self._direct: Any = None
        self._direct_initialised = False
        self._euclidean = True
        self.acceleration_limit: FloatArray | None = None
        self.q_nominal: FloatArray | None = None
        self._posture_reference: FloatArray | None = None
        self._last: tuple[FloatArray, FloatArray, FloatArray | None] | None = None
        self._step = 0

    # ------------------------------------------------------------------ set-up
    def bind(self, robot: Robot, dt: float) -> None:
        """Read the robot limits and build the persistent solver of the direct paths."""
        super().bind(robot, dt)
        nv = robot.nv
        self.acceleration_limit = per_joint(self.acceleration_limit_param, "acceleration_limit", nv)
        self.q_nominal = per_joint(self.q_nominal_param, "q_nominal", nv)
        self._euclidean = robot.nq == robot.nv
        self._buffers = BoxBuffers(
            robot.position_limits, robot.velocity_limits, dt, self.limit_gain,
            self.acceleration_limit,
        )  # fmt: skip
        # Preallocated QP data of the direct paths, written in place each QP step.
        self._hessian = np.empty((nv, nv))
        self._diagonal = self._hessian.reshape(-1)[:: nv + 1]  # a view on the diagonal
        self._linear = np.empty(nv)
        self._qp_bounds = np.empty((2, nv))  # [lb, ub] clipped to ±BIG
        self._qp_lower, self._qp_upper = self._qp_bounds[0], self._qp_bounds[1]
        self._direct = None
        if self.solver == "direct_daqp":
            import daqp

            self._direct = daqp.Model()
            self._no_rows = np.zeros((0, nv))  # box-only: no general constraint rows
        elif self.solver == "direct_proxsuite":
            import proxsuite

            qp = proxsuite.proxqp.dense.QP(nv, 0, 0, True)
            qp.settings.eps_abs = 1e-10
            qp.settings.eps_rel = 0.0
            qp.settings.verbose = False
            qp.settings.initial_guess = (
                proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
            )
            self._direct = qp
            self._direct_initialised = False
        elif self.solver == "direct_osqp":
            import osqp
            import scipy.sparse as sparse

            rows, cols = np.triu_indices(nv)
            order = np.lexsort((rows, cols))  # CSC order: by column, then row
            self._triu = (rows[order], cols[order])
            pattern = sparse.csc_matrix((np.ones(rows.size), self._triu), shape=(nv, nv))
            solver = osqp.OSQP()
            solver.setup(
                pattern,
                np.zeros(nv),
                sparse.identity(nv, format="csc"),
                -np.ones(nv),
                np.ones(nv),
                verbose=False,
                polishing=True,
                eps_abs=1e-10,
                eps_rel=1e-10,
                max_iter=20000,
            )
            self._direct = solver
        self.reset()

    def reset(self) -> None:
        """Forget the warm start, the step counter and a defaulted nominal posture."""
        self._step = 0
        self._last = None
        self._box = None
        self._box_inputs = None
        self._posture_reference = self.q_nominal
        self._direct_initialised = False

    # ------------------------------------------------------------------ problem
    @property
    def box(self) -> VelocityBox | None:
        """The :class:`VelocityBox` of the last step, or None before the first step."""
        if self._box is None and self._box_inputs is not None:
            self._box = self._velocity_box(*self._box_inputs)
        return self._box

    def _velocity_box(self, theta: FloatArray, qdot_prev: FloatArray) -> VelocityBox:
        robot = self.robot
        return velocity_box(
            theta, robot.position_limits, robot.velocity_limits, qdot_prev, self.dt,
            self.limit_gain, self.acceleration_limit,
        )  # fmt: skip

    @property
    def problem(self) -> qpsolvers.Problem | None:
        """The QP of the last step (see :func:`~otmm_qp_controllers.qp_problem.build_qp`)."""
        box = self.box
        if self._last is None or box is None:
            return None
        jacobian, xdot, posture = self._last
        return build_qp(
            jacobian, xdot, self.damping, box.lower, box.upper, self.posture_weight, posture
        )

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

    # ------------------------------------------------------------------ solve
    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Joint velocity [rad/s], shape ``(nv,)``, within the joint-velocity box."""
        step = self._step
        self._step += 1
        theta = state.q if self._euclidean else self.robot.joint_coordinates(state.q)
        buffers = self._buffers
        empty = buffers.update(theta, qdot_prev)
        self._box = None
        self._box_inputs = (
            theta,
            qdot_prev if self.acceleration_limit is None else qdot_prev.copy(),
        )
        posture = None
        if self.posture_weight > 0.0:
            if self._posture_reference is None:
                self._posture_reference = np.array(theta, dtype=float)
            posture = self.posture_gain * (self._posture_reference - theta)
        self._last = (state.task_jacobian, xdot, posture)
        self.used_qp = False
        if empty:
            box = self._box = self._velocity_box(*self._box_inputs)
            detail = box.conflict(self.robot.joint_names)
            return self._infeasible(step, detail, box, state, xdot, posture)
        lower, upper = buffers.lower, buffers.upper
        if self.fast_path:
            candidate = self.unconstrained(state, xdot, posture)
            margins = buffers.margins(candidate)
            if margins.min() >= 0.0:  # inside the box (False for NaN)
                status = STATUS_BOUNDED if buffers.any_active(margins, 1e-9) else STATUS_OK
                return BackendOutput(candidate, status, self.damping)
        self.used_qp = True
        qdot = self._solve_qp(state, xdot, posture, lower, upper)
        if qdot is None or not np.isfinite(qdot).all():
            detail = f"solver {self.solver!r} found no solution"
            box = self._box = self._velocity_box(*self._box_inputs)
            return self._infeasible(step, detail, box, state, xdot, posture)
        qdot = np.clip(qdot, lower, upper)
        return BackendOutput(qdot, self._status(qdot, 1e-7), self.damping)

    def _status(self, qdot: FloatArray, tol: float) -> str:
        """``bounded`` when some ``q̇_i`` is within ``tol·(1 + |bound|)`` of a bound."""
        buffers = self._buffers
        return STATUS_BOUNDED if buffers.any_active(buffers.margins(qdot), tol) else STATUS_OK

    def _solve_qp(
        self,
        state: KinematicState,
        xdot: FloatArray,
        posture: FloatArray | None,
        lower: FloatArray,
        upper: FloatArray,
    ) -> FloatArray | None:
        if self.solver not in DIRECT_SOLVERS:  # the plain reference path
            problem = build_qp(
                state.task_jacobian, xdot, self.damping, lower, upper, self.posture_weight,
                posture,
            )  # fmt: skip
            return solve_with_qpsolvers(problem, self.solver)
        self._fill_qp(state.task_jacobian, xdot, posture)
        if self.solver == "direct_daqp":
            return self._solve_daqp()
        if self.solver == "direct_proxsuite":
            return self._solve_proxsuite()
        return self._solve_osqp()

    def _fill_qp(self, jacobian: FloatArray, xdot: FloatArray, posture: FloatArray | None) -> None:
        r"""Write :func:`build_qp`'s ``P``, ``q``, ``lb``, ``ub`` into the preallocated arrays.

        .. math::
            P = J_w^\top J_w + (\lambda + w_p)I,\qquad q = -(J_w^\top\dot x_w + w_p\dot q_p)
        """
        hessian, linear = self._hessian, self._linear
        np.matmul(jacobian.T, jacobian, out=hessian)
        np.add(self._diagonal, self.damping + self.posture_weight, out=self._diagonal)
        np.matmul(jacobian.T, xdot, out=linear)
        np.negative(linear, out=linear)
        if self.posture_weight > 0.0 and posture is not None:
            linear -= self.posture_weight * posture
        np.clip(self._buffers.bounds, -BIG, BIG, out=self._qp_bounds)

    def _solve_daqp(self) -> FloatArray | None:
        model = self._direct
        if not self._direct_initialised:
            model.setup(self._hessian, self._linear, self._no_rows, self._qp_upper, self._qp_lower)
            self._direct_initialised = True
        else:  # keeps the previous active set: a warm start
            model.update(H=self._hessian, f=self._linear, bupper=self._qp_upper,
                         blower=self._qp_lower)  # fmt: skip
        x, _, exitflag, _ = model.solve()
        if exitflag <= 0:
            return None
        return np.array(x, dtype=float)

    def _solve_proxsuite(self) -> FloatArray | None:
        import proxsuite

        qp = self._direct
        hessian, linear, lower, upper = (
            self._hessian, self._linear, self._qp_lower, self._qp_upper
        )  # fmt: skip
        if not self._direct_initialised:
            qp.init(hessian, linear, None, None, None, None, None, lower, upper)
            self._direct_initialised = True
        else:
            qp.update(H=hessian, g=linear, l_box=lower, u_box=upper)
        qp.solve()
        if qp.results.info.status != proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED:
            return None
        return np.array(qp.results.x)

    def _solve_osqp(self) -> FloatArray | None:
        solver = self._direct
        rows, cols = self._triu
        solver.update(
            Px=self._hessian[rows, cols], q=self._linear, l=self._qp_lower, u=self._qp_upper
        )
        result = solver.solve(raise_error=False)
        if result.info.status_val not in (1, 2):  # solved, solved inaccurate
            return None
        return np.array(result.x)

    def _infeasible(
        self,
        step: int,
        detail: str,
        box: VelocityBox,
        state: KinematicState,
        xdot: FloatArray,
        posture: FloatArray | None,
    ) -> BackendOutput:
        if self.infeasible_policy == "raise":
            raise InfeasibleProblem(step, detail)
        lower, upper = box.relaxed()
        if self.infeasible_policy == "hold":
            qdot = np.clip(np.zeros_like(lower), lower, upper)
        else:
            qdot = np.clip(self.unconstrained(state, xdot, posture), lower, upper)
        return BackendOutput(qdot, STATUS_INFEASIBLE, self.damping)
