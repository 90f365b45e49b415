r"""QP differential inverse kinematics with joint limits (pink / mink style)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from numbers import Real
from typing import Any, ClassVar, Literal

import numpy as np

from otmm_qp.backends.backend import BackendOutput, damping_weight, svd_work
from otmm_qp.limits import Box, LimitSpec, Row, make_limits, per_joint
from otmm_qp.limits.options import LIMITS, removed_limit_keys
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.status import Status
from otmm_qp.validation import (
    Boolean,
    Constraints,
    InstanceOf,
    Interval,
    OneOf,
    check_params,
)

from .box_backend import SOLVER, SOLVER_TOL, BoxQpBackend, QpStep
from .formulation import (
    BIG,
    QpFormulation,
    QpProblem,
    active_bound,
    build_qp,
    clip_into_box,
    diagonal_view,
)
from .posture import POSTURE_MOVED, QpPosture
from .solvers import QpSession, available_solvers, make_session

InfeasiblePolicy = Literal["raise", "hold", "dls"]
POLICIES = ("raise", "hold", "dls")
#: ``μ`` when neither ``damping`` nor ``regularization`` is given (λ ≈ 0.0316).
DEFAULT_REGULARIZATION = 1e-3

__all__ = ["POLICIES", "InfeasiblePolicy", "QpBackend", "QpStep", "available_solvers"]

#: Builds a NamedTuple from all its fields without the Python-level ``__new__`` (hot path).
_new = tuple.__new__

#: ``damping`` λ or ``regularization`` μ of the QP backends: > 0, or None (the other / default).
POSITIVE_OR_NONE = [Interval(Real, 0, None, closed="neither"), None]


class QpBackend(BoxQpBackend):
    r"""Damped least squares under the step's joint limits: the QP of :class:`QpFormulation`.

    .. math::
        \min_{\dot q}\ \tfrac12\|J_w\dot q - \dot x_w\|^2 + \tfrac12\lambda^2\|\dot q\|^2
        + \tfrac12 w_p\|\dot q - g_p(\theta_{nom} - \theta)\|^2
        \quad\text{s.t.}\quad lb \le \dot q \le ub,\quad c_j^\top\dot q \ge l_j

    with the box ``[lb; ub]`` of the box limits (:mod:`otmm_qp.limits`) and the rows of the
    row limits (the singularity barrier). Without posture cost and with no bound active the
    solution is DLS with damping λ; ``BackendOutput.damping`` reports λ [task units], as every
    DLS backend does.

    One step: the box (:meth:`begin_step`, with soft command limits composed braking first:
    status ``relaxed`` when one was given up); if it is empty, the policy. Else the fast path:
    the unconstrained minimiser :meth:`QpFormulation.unconstrained` from the shared SVD, kept
    when it lies in the box (convexity makes it the QP optimum then); else the QP
    (:meth:`QpFormulation.build`) in the persistent session, its answer clipped into the box
    (removing solver tolerance, so a returned ``q̇`` never violates a bound). Row limits are
    lazy: only when that optimum violates one is the QP re-solved with every applicable row
    (in a second session, so neither loses its warm start). ``BackendOutput.details`` is the
    :class:`~otmm_qp_controllers.qp.box_backend.QpStep` of what was solved.

    Args:
        damping: λ > 0 [task units] (μ = λ²), the meaning ``damping`` has in every backend.
        regularization: μ = λ² > 0 [task units² / (rad/s)²] instead of ``damping``; μ = 10⁻³
            when neither is given.
        solver: ``daqp``, ``proxsuite``, ``osqp`` (persistent sessions, warm started) or
            another installed qpsolvers backend (``quadprog``, ``clarabel``, ``proxqp``:
            solved from scratch each step).
        limits: Limit objects or ``{type: NAME, ...}`` entries (:mod:`otmm_qp.limits.options`);
            None: the robot's speed limit and ``{type: position, gain: 0.5}``.
        posture: The posture cost ``{weight: w_p, gain: g_p, q_nominal: θ_nom}``
            (:class:`~.posture.QpPosture`; ``q_nominal`` omitted: the first state seen after
            :meth:`reset`); None: no posture cost.
        infeasible_policy: ``raise``, ``hold`` or ``dls`` (``dls`` clips ``q̇*`` into the
            relaxed box).
        fast_path: Skip the QP when the unconstrained minimiser is feasible.

    The older keys ``limit_gain``, ``acceleration_limit`` and ``singularity_barrier`` are
    refused with the ``limits`` list to write instead (``removed_parameters``,
    :func:`~otmm_qp.limits.options.removed_limit_keys`), and ``posture_weight``,
    ``posture_gain``, ``q_nominal`` with the ``posture`` block.

    Raises:
        ParameterError: A parameter out of range.
        SolverNotFound: ``solver`` is not installed.
    """

    name = "qp"
    policies = POLICIES
    parameter_constraints: ClassVar[Constraints] = {
        "damping": POSITIVE_OR_NONE,
        "regularization": POSITIVE_OR_NONE,
        "solver": SOLVER,
        "limits": [LIMITS, None],
        "posture": [
            InstanceOf((Mapping, QpPosture), "a mapping {weight: ..., gain: ..., q_nominal: ...}"),
            None,
        ],
        "infeasible_policy": OneOf(*POLICIES),
        "fast_path": Boolean(),
    }
    removed_parameters: ClassVar[Mapping[str, str]] = {
        **removed_limit_keys("limit_gain", "acceleration_limit", "singularity_barrier"),
        **POSTURE_MOVED,
    }

    def __init__(
        self,
        damping: float | None = None,
        regularization: float | None = None,
        solver: str = "daqp",
        limits: Sequence[LimitSpec] | None = None,
        posture: QpPosture | Mapping[str, Any] | None = None,
        infeasible_policy: InfeasiblePolicy = "raise",
        fast_path: bool = True,
    ) -> None:
        check_params(self, locals())
        mu = damping_weight(damping, regularization, DEFAULT_REGULARIZATION, positive=True)
        super().__init__(solver, make_limits(limits), infeasible_policy)
        self.posture = QpPosture.from_spec(posture)
        self.formulation = QpFormulation(mu, self.posture.weight)
        self.posture_gain = self.posture.gain
        self.q_nominal_param = self.posture.q_nominal
        self.q_nominal: FloatArray | None = None
        self.fast_path = bool(fast_path)
        self._row_session: QpSession | None = make_session(solver) if self.limits.rows else None
        self._factor = self.formulation.damping
        self._posture_reference: FloatArray | None = None
        self._work: FloatArray | None = None  # svd_work buffers, allocated by bind

    def bind(self, robot: Robot, dt: float) -> None:
        """Bind the limits; allocate the QP data written in place each step."""
        self.q_nominal = per_joint(self.q_nominal_param, "posture.q_nominal", robot.nv)
        super().bind(robot, dt)
        # With finite speed limits every non-empty box lies within ±BIG: the box is then
        # written straight into the problem's lb/ub (no copy, no clipping per step).
        static = self.box.static
        self._box_in_problem = bool(np.all(static.upper <= BIG) and np.all(static.lower >= -BIG))
        box = self.box.bounds if self._box_in_problem else None
        self._data = QpProblem.allocate(robot.nv, box=box)
        self._diagonal = diagonal_view(self._data.P)
        self._row_data = QpProblem.allocate(robot.nv, len(self.limits.rows))
        self._work = svd_work(robot)

    def reset(self) -> None:
        """Forget warm starts and a defaulted nominal posture."""
        super().reset()
        if self._row_session is not None:
            self._row_session.reset()
        self._posture_reference = self.q_nominal

    def _posture(self, theta: FloatArray) -> FloatArray:
        """``q̇_p = g_p(θ_nom − θ)`` [rad/s], shape ``(nv,)`` (``θ_nom``: the first θ if unset)."""
        if self._posture_reference is None:
            self._posture_reference = np.array(theta, dtype=float)
        return self.posture_gain * (self._posture_reference - theta)

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Joint velocity [rad/s], shape ``(nv,)``, within the box; ``details`` a ``QpStep``."""
        theta, empty = self.begin_step(state, qdot_prev)
        formulation = self.formulation
        posture = None if formulation.posture_weight <= 0.0 else self._posture(theta)
        inputs: StepInputs = (state, xdot, posture)
        if empty:
            return self._empty_box(inputs)
        qdot, status, record = self._solve_box(inputs)
        session = self._row_session
        if session is not None and status in (Status.OK, Status.BOUNDED):
            qdot, status, record = self._enforce_rows(inputs, session, qdot, status)
        if self.box.softened and status in (Status.OK, Status.BOUNDED):
            status = Status.RELAXED  # a soft (command) box was given up, braking first
        # tuple.__new__: the NamedTuple without its Python-level __new__ (a third cheaper).
        return _new(BackendOutput, (qdot, status, self._factor, 1.0, record))

    def _empty_box(self, inputs: StepInputs) -> BackendOutput:
        """The policy's answer to an empty box (``raise`` carries the step's QP)."""
        state, xdot, posture = inputs
        bounds = self.box.bounds
        problem = self.formulation.build(
            state.task_jacobian, xdot, posture, bounds, QpProblem.allocate(state.jacobian.shape[1])
        )
        detail = self.box.conflict(self.robot.joint_names)
        preferred = self.formulation.unconstrained(state, xdot, posture)
        qdot, status = self.fallback(detail, (problem, None), True, preferred)
        return BackendOutput(qdot, status, self._factor, details=QpStep(bounds, problem))

    def _solve_box(self, inputs: StepInputs) -> tuple[FloatArray, Status, QpStep]:
        """The optimum under the box: the fast path when it applies, else the QP."""
        state, xdot, posture = inputs
        box, formulation = self.box, self.formulation
        if self.fast_path:
            candidate = formulation.unconstrained(state, xdot, posture, self._work)
            active = active_bound(candidate, box.bounds, 1e-9, box.lists)  # None: outside, NaN
            if active is not None:
                return candidate, Status.BOUNDED if active else Status.OK, QpStep(box.bounds)
        data = build_qp(
            state.task_jacobian, xdot, formulation.mu,
            None if self._box_in_problem else box.bounds,  # None: already in _data
            formulation.posture_weight, posture, self._data, self._diagonal,
        )  # fmt: skip
        return self._solve(inputs, self.session, data, ())

    def _solve(
        self, inputs: StepInputs, session: QpSession, data: QpProblem, rows: tuple[Row, ...]
    ) -> tuple[FloatArray, Status, QpStep]:
        """Solve ``data`` in ``session``; clip into the box, or fall back on failure."""
        session.load(data)
        solution = session.solve()
        box = self.box
        bounds = box.bounds
        record = _new(QpStep, (bounds, data, solution, rows))  # QpStep(...), cheaper
        x = solution.x  # a fresh array (the session contract): returned when not clipped
        settled = None if x is None else clip_into_box(x, bounds, SOLVER_TOL, box.lists, owned=True)
        if settled is None:  # no solution, or a non-finite one
            state, xdot, posture = inputs
            detail = f"solver {self.solver!r} found no solution ({solution.detail})"
            preferred = self.formulation.unconstrained(state, xdot, posture)
            evidence = (data.copy(), solution)
            qdot, status = self.fallback(detail, evidence, False, preferred)
            return qdot, status, record
        qdot, active = settled
        return qdot, Status.BOUNDED if active else Status.OK, record

    def _enforce_rows(
        self, inputs: StepInputs, session: QpSession, qdot: FloatArray, status: Status
    ) -> tuple[FloatArray, Status, QpStep]:
        """Keep ``qdot`` if it meets every row limit, else re-solve with every applicable row."""
        state, xdot, posture = inputs
        applicable = [limit for limit in self.limits.rows if limit.applies(state)]
        bounds = self.box.bounds
        if all(limit.satisfied(state, qdot) for limit in applicable):
            return qdot, status, QpStep(bounds)
        data = self._row_data
        finite = np.clip(bounds, -BIG, BIG)
        box = Box(finite[0], finite[1])
        rows = []
        data.C[:] = 0.0
        data.l[:] = -BIG
        for j, limit in enumerate(self.limits.rows):
            if limit in applicable:
                row = limit.compute_row(state, box)
                rows.append(row)
                data.C[j], data.l[j] = row.row, row.lower
        self.formulation.build(state.task_jacobian, xdot, posture, bounds, data)
        qdot, status, record = self._solve(inputs, session, data, tuple(rows))
        if status in (Status.OK, Status.BOUNDED):
            relaxed = any(row.slack > 0.0 for row in rows)
            status = Status.RELAXED if relaxed else Status.BOUNDED
        return qdot, status, record


#: One step's inputs: ``(state, ẋ_w (n,), q̇_p (nv,) or None)``.
StepInputs = tuple[KinematicState, FloatArray, FloatArray | None]
