r"""What the box-constrained QP backends share: the limits, the session, the policy, statuses.

:class:`BoxQpBackend` holds a backend's :class:`~otmm_qp.limits.box.LimitBox` (evaluated in
place each step by :meth:`~BoxQpBackend.begin_step`), its persistent
:class:`~otmm_qp_controllers.qp.solvers.QpSession` and its infeasibility policy
(:meth:`~BoxQpBackend.fallback`), and classifies a solution as ``ok`` or ``bounded``.
:class:`QpStep` is the record of what a step solved, returned in ``BackendOutput.details``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar, NamedTuple

import numpy as np

from otmm_qp.backends.backend import Backend
from otmm_qp.exceptions import InfeasibleProblem, SolverNotConverged
from otmm_qp.limits import LimitBox, LimitSet, Row
from otmm_qp.plants.declaration import PlantDeclaration
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.status import Status
from otmm_qp.validation import InstanceOf

from .formulation import active_bound
from .solvers import (
    QpProblem,
    QpSession,
    Solution,
    available_solvers,
    make_session,
    unknown_solver,
)

#: Tolerance of :meth:`BoxQpBackend.classify` on a solver's answer (solvers stop at ~1e-10).
SOLVER_TOL = 1e-7

#: ``solver`` of the QP backends (whether it is installed is checked at construction, raising
#: :class:`~otmm_qp.exceptions.SolverNotFound` with the installed ones).
SOLVER = InstanceOf((str,), "a QP solver name (daqp, proxsuite, osqp, or a qpsolvers one)")


class QpStep(NamedTuple):
    """What one step of a QP backend solved (``BackendOutput.details``).

    The arrays are the backend's buffers, valid until its next step (copy to keep).

    Attributes:
        bounds: The step's box ``[lb; ub]`` [rad/s], shape ``(2, nv)``.
        problem: The QP handed to the solver, or None when none was (fast path, empty box).
        solution: The solver's answer to ``problem``, or None.
        rows: The row limits' rows the QP enforced (empty: none, or the optimum under the
            box already satisfied them).
    """

    bounds: FloatArray
    problem: QpProblem | None = None
    solution: Solution | None = None
    rows: tuple[Row, ...] = ()


class BoxQpBackend(Backend):
    r"""Base of the QP backends: the box ``lb ≤ q̇ ≤ ub`` of the step's limits, a solver, a policy.

    Infeasible steps follow ``infeasible_policy``:

    * ``raise``: :class:`~otmm_qp.exceptions.InfeasibleProblem` carrying the step's problem
      and the solver's answer;
    * ``hold``: zero velocity clipped into the *relaxed* box (limits honoured by priority
      velocity > position > acceleration, :func:`otmm_qp.limits.box.relaxed`);
    * ``dls`` (where offered): the subclass's unconstrained solution clipped likewise.

    A non-raising policy reports ``relaxed`` when the box was empty (a bound was given up) and
    ``infeasible`` when the box was not empty but the solver found no solution.

    Subclasses implement :meth:`solve`: :meth:`begin_step`, then their formulation, then
    :meth:`classify` or :meth:`fallback`.

    Args:
        solver: A name of :func:`~otmm_qp_controllers.qp.solvers.available_solvers`.
        limits: The backend's limits (:func:`otmm_qp.limits.make_limits`).
        infeasible_policy: One of :attr:`policies`.
        solvers: The solver names this backend accepts (all available ones when None).

    Attributes:
        limits: The :class:`~otmm_qp.limits.LimitSet`.
        box: Its box limits' :class:`~otmm_qp.limits.LimitBox`; ``box.bounds`` is the last
            step's ``[lb; ub]`` [rad/s], shape ``(2, nv)``.
        session: The persistent :class:`~otmm_qp_controllers.qp.solvers.QpSession`.
    """

    #: Accepted ``infeasible_policy`` values.
    policies: ClassVar[tuple[str, ...]] = ("raise", "hold")
    enforces_limits = True

    def __init__(
        self,
        solver: str,
        limits: LimitSet,
        infeasible_policy: str,
        solvers: Sequence[str] | None = None,
    ) -> None:
        installed = available_solvers() if solvers is None else solvers
        if solver not in installed:
            raise unknown_solver(solver, installed)
        self.solver = solver
        self.limits = limits
        self.box = LimitBox(limits.boxes)
        self.infeasible_policy = infeasible_policy
        self.session: QpSession = make_session(solver)

    def bind(self, robot: Robot, dt: float) -> None:
        """Bind the limits and allocate the box; forget the last run."""
        super().bind(robot, dt)
        self.box.bind(robot, dt)
        for row in self.limits.rows:
            row.bind(robot, dt)
        self._euclidean = robot.nq == robot.nv
        self.reset()

    def declare_plant(self, declaration: PlantDeclaration) -> None:
        """Hand the plant's declaration to the limits (read at :meth:`bind`)."""
        self.box.declare_plant(declaration)

    def reset(self) -> None:
        """Forget the solver's warm start and the limits' per-step state."""
        self.session.reset()
        self.box.reset()

    def begin_step(self, state: KinematicState, qdot_prev: FloatArray) -> tuple[FloatArray, bool]:
        """Write the step's box into ``box.bounds``.

        Returns:
            ``(joint coordinates θ (nv,), whether the box is empty)``.
        """
        theta = state.q if self._euclidean else self.robot.joint_coordinates(state.q)
        return theta, self.box.compute(theta, qdot_prev)

    def brake(self) -> tuple[FloatArray, Status]:
        """Zero velocity clipped into the step's (non-empty, braking-first) box, ``relaxed``.

        The answer of a backend with soft command limits when its problem has no solution
        under the box (e.g. ``qp_scaled``'s ``J q̇ = α ẋ`` away from the box): the task is
        given up for the step and every joint slows down as fast as its limits allow.
        """
        lower, upper = self.box.bounds
        return np.clip(np.zeros_like(lower), lower, upper), Status.RELAXED

    def classify(self, qdot: FloatArray, tol: float) -> Status:
        """``bounded`` when some ``q̇_i`` is within ``tol·(1 + |bound|)`` of (or beyond) a bound."""
        return self.inside_status(qdot, tol) or Status.BOUNDED

    def inside_status(self, qdot: FloatArray, tol: float) -> Status | None:
        """:meth:`classify` for ``qdot`` inside the box; None when it is outside (or NaN)."""
        box = self.box
        active = active_bound(qdot, box.bounds, tol, box.lists)
        if active is None:
            return None
        return Status.BOUNDED if active else Status.OK

    def fallback(
        self,
        detail: str,
        evidence: tuple[QpProblem | None, Solution | None],
        empty: bool,
        preferred: FloatArray | None = None,
    ) -> tuple[FloatArray, Status]:
        """Apply the infeasibility policy to a step with no solution.

        Args:
            detail: One-line reason (which joint's boxes conflict, or the solver's answer).
            evidence: The step's QP (None if not built) and the solver's answer (None when
                the solver was not called): carried by the ``raise`` policy's error.
            empty: Whether the box was empty (status ``relaxed``; else ``infeasible``).
            preferred: The velocity the ``dls`` policy clips (``hold`` clips zero).

        Returns:
            ``(q̇ inside the relaxed box, relaxed | infeasible)``.

        Raises:
            InfeasibleProblem: The policy is ``raise`` (without the step index: the loop that
                runs the backend states it).
            SolverNotConverged: The policy is ``raise`` and the solver stopped before
                converging (``Solution.converged`` false): the problem was not shown
                infeasible. The ``hold`` and ``dls`` policies treat both alike.
        """
        solution = evidence[1]
        if solution is not None and not solution.converged:
            detail = (
                f"solver {self.solver!r} stopped before converging ({solution.detail}); the "
                "problem was not shown infeasible"
            )
            if self.infeasible_policy == "raise":
                raise SolverNotConverged(None, detail, *evidence)
        elif self.infeasible_policy == "raise":
            raise InfeasibleProblem(None, detail, *evidence)
        lower, upper = self.box.relaxed()
        target = np.zeros_like(lower)
        if self.infeasible_policy == "dls" and preferred is not None:
            target = preferred
        status = Status.RELAXED if empty else Status.INFEASIBLE
        return np.clip(target, lower, upper), status
