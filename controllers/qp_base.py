r"""What the box-constrained QP backends share: parameters, the box, failures, statuses.

:class:`BoxQpBackend` validates the joint-limit parameters and the solver name, reads the
robot's limits in :meth:`~BoxQpBackend.bind`, evaluates the joint-velocity box of each step
(:func:`~otmm_qp_controllers.qp_problem.velocity_bounds` into preallocated arrays), applies
the infeasibility policy and classifies a solution as ``ok`` or ``bounded``.
"""

from __future__ import annotations

import operator
from collections.abc import Sequence

import numpy as np

from otmm_qp.backends.backend import Backend
from otmm_qp.exceptions import InfeasibleProblem, SolverNotFound
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.status import Status
from otmm_qp_controllers.qp_problem import (
    JointLimits,
    VelocityBox,
    active_bound,
    check_limit_parameters,
    per_joint,
    velocity_bounds,
    velocity_box,
)
from otmm_qp_controllers.qp_solvers import (
    QpProblem,
    QpSession,
    Solution,
    available_solvers,
    make_session,
)

#: Tolerance of :meth:`BoxQpBackend.classify` on a solver's answer (solvers stop at ~1e-10).
SOLVER_TOL = 1e-7


class BoxQpBackend(Backend):
    r"""Base of the QP backends: a joint-velocity box ``lb ≤ q̇ ≤ ub`` every step.

    Infeasible steps follow ``infeasible_policy``:

    * ``raise``: :class:`~otmm_qp.exceptions.InfeasibleProblem` carrying the step's problem
      and the solver's answer;
    * ``hold``: zero velocity clipped into the *relaxed* box (limits honoured by priority
      velocity > position > acceleration, see :meth:`VelocityBox.relaxed`);
    * ``dls`` (where offered): the subclass's unconstrained solution clipped likewise.

    A non-raising policy reports ``relaxed`` when the box was empty (a bound was given up) and
    ``infeasible`` when the box was not empty but the solver found no solution.

    Args:
        solver: A name of :func:`~otmm_qp_controllers.qp_solvers.available_solvers`.
        limit_gain: ``g ∈ (0, 1]`` of the position-limit velocity bounds.
        acceleration_limit: ``a_max`` [rad/s²], scalar or shape ``(nv,)``; None: no limit.
        infeasible_policy: One of :attr:`policies`.
        solvers: The solver names this backend accepts (all available ones when None).

    Attributes:
        bounds: ``[lb; ub]`` [rad/s] of the last step, shape ``(2, nv)`` (overwritten each step).
        session: The persistent :class:`~otmm_qp_controllers.qp_solvers.QpSession`.
    """

    #: Accepted ``infeasible_policy`` values.
    policies: tuple[str, ...] = ("raise", "hold")

    def __init__(
        self,
        solver: str,
        limit_gain: float,
        acceleration_limit: float | Sequence[float] | None,
        infeasible_policy: str,
        solvers: Sequence[str] | None = None,
    ) -> None:
        installed = available_solvers() if solvers is None else solvers
        if solver not in installed:
            raise SolverNotFound(solver, installed)
        check_limit_parameters(limit_gain, infeasible_policy, self.policies, acceleration_limit)
        self.solver = solver
        self.limit_gain = float(limit_gain)
        self.acceleration_limit_param = acceleration_limit
        self.acceleration_limit: FloatArray | None = None
        self.infeasible_policy = infeasible_policy
        self.session: QpSession = make_session(solver)
        self._box_inputs: tuple[FloatArray, FloatArray] | None = None
        self._euclidean = True
        self._step = 0

    def bind(self, robot: Robot, dt: float) -> None:
        """Read the robot's limits and allocate the per-step arrays."""
        super().bind(robot, dt)
        nv = robot.nv
        self.acceleration_limit = per_joint(self.acceleration_limit_param, "acceleration_limit", nv)
        self.limits = JointLimits.make(
            robot.position_limits, robot.velocity_limits, dt, self.limit_gain,
            self.acceleration_limit,
        )  # fmt: skip
        self._euclidean = robot.nq == robot.nv
        self.bounds = np.empty((2, nv))
        self._scratch = np.empty((2, nv))
        self.reset()

    def reset(self) -> None:
        """Forget the step counter, the last box and the solver's warm start."""
        self._step = 0
        self._box_inputs = None
        self.session.reset()

    def begin_step(
        self, state: KinematicState, qdot_prev: FloatArray
    ) -> tuple[int, FloatArray, bool]:
        """Count the step and write its box into :attr:`bounds`.

        Returns:
            ``(step index, joint coordinates θ (nv,), whether the box is empty)``.
        """
        step = self._step
        self._step += 1
        theta = state.q if self._euclidean else self.robot.joint_coordinates(state.q)
        velocity_bounds(theta, qdot_prev, self.limits, out=self.bounds, scratch=self._scratch)
        keep_prev = qdot_prev if self.acceleration_limit is None else qdot_prev.copy()
        self._box_inputs = (theta, keep_prev)
        lower, upper = self.bounds.tolist()
        # A scalar test: a third of the cost of NumPy's greater + any on arm-sized nv.
        return step, theta, any(map(operator.gt, lower, upper))

    @property
    def box(self) -> VelocityBox | None:
        """Every box of the last step (pure :func:`velocity_box`), or None before a step."""
        if self._box_inputs is None:
            return None
        robot = self.robot
        return velocity_box(
            self._box_inputs[0], robot.position_limits, robot.velocity_limits,
            self._box_inputs[1], self.dt, self.limit_gain, self.acceleration_limit,
        )  # fmt: skip

    def classify(self, qdot: FloatArray, tol: float) -> Status:
        """``bounded`` when some ``q̇_i`` is within ``tol·(1 + |bound|)`` of (or beyond) a bound."""
        return self.inside_status(qdot, tol) or Status.BOUNDED

    def inside_status(self, qdot: FloatArray, tol: float) -> Status | None:
        """:meth:`classify` for ``qdot`` inside the box; None when it is outside (or NaN)."""
        active = active_bound(qdot, self.bounds, tol)
        if active is None:
            return None
        return Status.BOUNDED if active else Status.OK

    def fallback(
        self,
        step: int,
        detail: str,
        problem: QpProblem | None,
        solution: Solution | None,
        preferred: FloatArray | None = None,
    ) -> tuple[FloatArray, Status]:
        """Apply the infeasibility policy to a step with no solution.

        Args:
            step: Step index.
            detail: One-line reason (which joint's boxes conflict, or the solver's answer).
            problem: The step's QP (evidence for ``raise``).
            solution: The solver's answer, None when the solver was not called.
            preferred: The velocity the ``dls`` policy clips (``hold`` clips zero).

        Returns:
            ``(q̇ inside the relaxed box, relaxed | infeasible)``.
        """
        if self.infeasible_policy == "raise":
            raise InfeasibleProblem(step, detail, problem, solution)
        box = self.box
        assert box is not None  # noqa: S101 - begin_step ran this step
        lower, upper = box.relaxed()
        target = np.zeros_like(lower)
        if self.infeasible_policy == "dls" and preferred is not None:
            target = preferred
        status = Status.RELAXED if box.empty else Status.INFEASIBLE
        return np.clip(target, lower, upper), status
