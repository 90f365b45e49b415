r"""Direction-preserving QP differential IK after Drake's ``DoDifferentialInverseKinematics``."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from numbers import Real
from typing import ClassVar, Literal

import numpy as np
import numpy.typing as npt
import qpsolvers

from otmm_qp.backends.backend import BackendOutput, rank_cutoff
from otmm_qp.exceptions import ParameterError
from otmm_qp.limits import LimitSpec, make_limits
from otmm_qp.limits.options import LIMITS, removed_limit_keys
from otmm_qp.robots.robot import FloatArray
from otmm_qp.state import KinematicState
from otmm_qp.status import Status
from otmm_qp.validation import Constraints, Interval, OneOf, check_params

from .box_backend import SOLVER, SOLVER_TOL, BoxQpBackend, QpStep
from .formulation import BIG, QpProblem, clip_into_box
from .solvers import SESSIONS, Solution

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

    with the box ``[lb; ub]`` of the step's box limits (:mod:`otmm_qp.limits`). Drake uses the
    linear cost ``−100α`` plus a null-space posture cost; here the QP of
    :func:`build_scaled_qp` is solved, ``−α + ε/2(‖q̇‖² + α²)``: the small ``ε`` makes the
    Hessian positive definite (quadprog, proxqp need it) and picks the minimum-norm ``q̇``;
    it lowers α below its maximum only when ``ε(1 + ‖q̇‖²/α²) > 1``.

    Near a singularity the equality forces ``α → 0`` for commands along the lost direction:
    that is a result (status ``stuck``), not a failure. When the pseudoinverse solution
    already lies in the box it is returned with ``α = 1`` without calling the solver.
    ``BackendOutput.scale`` is α; ``details`` the :class:`~.box_backend.QpStep`.

    Args:
        solver: One of :data:`SCALED_SOLVERS` that is installed.
        limits: Box limits or ``{type: NAME, ...}`` entries (:mod:`otmm_qp.limits.options`);
            None: the robot's speed limit and ``{type: position, gain: 0.5}``. Row limits
            (the singularity barrier) are refused.
        stuck_threshold: Status ``stuck`` when ``α`` is below it, in ``[0, 1]``.
        regularization: ``ε > 0``.
        infeasible_policy: ``raise`` (:class:`~otmm_qp.exceptions.InfeasibleProblem`) or
            ``hold`` (zero speed clipped into the relaxed box, ``α = 0``), used when the box
            is empty or no ``(q̇, α)`` exists (e.g. the box excludes ``q̇ = 0`` while ``J_w``
            has no null space).

    With a soft command limit (:mod:`otmm_qp.limits.command_limit`) a step whose QP has no
    solution under the braking-first box brakes instead (zero clipped into that box, ``α = 0``,
    status ``relaxed``, :meth:`~.box_backend.BoxQpBackend.brake`): never an infeasible QP.

    The older keys ``limit_gain`` and ``acceleration_limit`` are refused with the ``limits``
    list to write instead (``removed_parameters``).
    """

    name = "qp_scaled"
    policies = POLICIES
    parameter_constraints: ClassVar[Constraints] = {
        "solver": SOLVER,
        "limits": [LIMITS, None],
        "stuck_threshold": Interval(Real, 0, 1, closed="both"),
        "regularization": Interval(Real, 0, None, closed="neither"),
        "infeasible_policy": OneOf(*POLICIES),
    }
    removed_parameters: ClassVar[Mapping[str, str]] = removed_limit_keys(
        "limit_gain", "acceleration_limit"
    )

    def __init__(
        self,
        solver: str = "daqp",
        limits: Sequence[LimitSpec] | None = None,
        stuck_threshold: float = 0.1,
        regularization: float = 1e-6,
        infeasible_policy: Literal["raise", "hold"] = "raise",
    ) -> None:
        check_params(self, locals())
        installed = set(qpsolvers.available_solvers) | set(SESSIONS)
        allowed = [s for s in SCALED_SOLVERS if s in installed]
        limit_set = make_limits(limits)
        if limit_set.rows:
            names = ", ".join(row.name for row in limit_set.rows)
            raise ParameterError("limits", f"qp_scaled takes box limits only, not {names}")
        super().__init__(solver, limit_set, infeasible_policy, allowed)
        self.stuck_threshold = float(stuck_threshold)
        self.regularization = float(regularization)

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Joint velocity [rad/s] realising ``α ẋ_w``; ``BackendOutput.scale = α``."""
        _, empty = self.begin_step(state, qdot_prev)
        bounds = self.box.bounds
        if empty:
            problem = build_scaled_qp(state, xdot, bounds, self.regularization)
            detail = self.box.conflict(self.robot.joint_names)
            return self._fail(detail, (problem, None), True)
        keep, inside = range_split(state, xdot)
        if inside:
            sigma = state.sigma
            candidate = state.Vt[keep].T @ ((state.U[:, keep].T @ xdot) / sigma[keep])
            lower, upper = bounds
            if np.all(candidate >= lower) and np.all(candidate <= upper):
                status = self._status(candidate, 1.0, 1e-9)
                if self.box.softened:
                    status = Status.RELAXED
                return BackendOutput(candidate, status, scale=1.0, details=QpStep(bounds))
        problem = build_scaled_qp(state, xdot, bounds, self.regularization)
        self.session.load(problem)
        solution = self.session.solve()
        x = solution.x
        settled = None if x is None else clip_into_box(x[:-1], bounds, SOLVER_TOL)
        if x is None or settled is None or not np.isfinite(x[-1]):
            if self.box.has_soft:
                qdot, status = self.brake()
                return BackendOutput(qdot, status, scale=0.0, details=QpStep(bounds, problem))
            detail = f"solver {self.solver!r} found no (q̇, α) with J q̇ = α ẋ inside the box"
            return self._fail(detail, (problem, solution), False)
        alpha = float(np.clip(x[-1], 0.0, 1.0))
        qdot, active = settled
        status = Status.STUCK if alpha < self.stuck_threshold else (
            Status.BOUNDED if active else Status.OK
        )  # fmt: skip
        if self.box.softened and status is not Status.STUCK:
            status = Status.RELAXED
        details = QpStep(bounds, problem, solution)
        return BackendOutput(qdot, status, scale=alpha, details=details)

    def _status(self, qdot: FloatArray, alpha: float, tol: float) -> Status:
        return Status.STUCK if alpha < self.stuck_threshold else self.classify(qdot, tol)

    def _fail(
        self,
        detail: str,
        evidence: tuple[QpProblem | None, Solution | None],
        empty: bool,
    ) -> BackendOutput:
        qdot, status = self.fallback(detail, evidence, empty)
        details = QpStep(self.box.bounds, *evidence)
        return BackendOutput(qdot, status, scale=0.0, details=details)
