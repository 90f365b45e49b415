r"""Building blocks of the QP differential-IK backends: joint-velocity boxes and the QP.

Every joint limit of the velocity-level problem is a box on ``q̇`` (shape ``(nv,)``):

.. math::
    \underbrace{-\dot q_{max}}_{\text{velocity}} \le \dot q \le \dot q_{max},\qquad
    \underbrace{-g\frac{\theta - \theta_{min}}{dt}}_{\text{position}} \le \dot q \le
    g\frac{\theta_{max} - \theta}{dt},\qquad
    \underbrace{\dot q_{prev} - a_{max}dt}_{\text{acceleration}} \le \dot q \le
    \dot q_{prev} + a_{max}dt

so the feasible set is their intersection ``[lb, ub]`` and it is empty exactly when some
``lb_i > ub_i`` (e.g. a start outside the position limits farther than ``v_max·dt/g``).
Building (:func:`build_qp`) is kept apart from solving (the backends).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
import qpsolvers

from otmm_qp.exceptions import DimensionError, ParameterError
from otmm_qp.robots.robot import FloatArray

#: Infinite bounds are passed to the solvers as ±BIG [rad/s] (some reject inf).
BIG = 1e9

#: Solver options giving ~1e-10 accuracy; active-set solvers (daqp, quadprog) are exact.
#: (Residual tolerances act on ``Hq̇``, so the error on ``q̇`` is about ``eps/λ``.)
SOLVER_OPTIONS: dict[str, dict[str, Any]] = {
    "clarabel": {"tol_gap_abs": 1e-12, "tol_gap_rel": 1e-12, "tol_feas": 1e-12},
    "daqp": {},
    "osqp": {"eps_abs": 1e-10, "eps_rel": 1e-10, "polishing": True, "max_iter": 20000},
    "proxqp": {"eps_abs": 1e-12, "eps_rel": 0.0, "max_iter": 100000},
    "quadprog": {},
}

#: qpsolvers backends that want a sparse ``P`` (a dense one only triggers a warning).
SPARSE_SOLVERS = ("clarabel", "osqp")


def solve_with_qpsolvers(problem: qpsolvers.Problem, solver: str) -> FloatArray | None:
    """Solve ``problem`` with the named qpsolvers backend at :data:`SOLVER_OPTIONS` accuracy.

    Returns:
        The solution, or None when the solver reports none.
    """
    if solver in SPARSE_SOLVERS:
        import scipy.sparse as sparse

        problem = qpsolvers.Problem(
            sparse.csc_matrix(problem.P),
            problem.q,
            None if problem.G is None else sparse.csc_matrix(problem.G),
            problem.h,
            None if problem.A is None else sparse.csc_matrix(problem.A),
            problem.b,
            problem.lb,
            problem.ub,
        )
    options = SOLVER_OPTIONS.get(solver, {})
    if solver != "osqp":
        solution = qpsolvers.solve_problem(problem, solver=solver, **options)
    else:
        with warnings.catch_warnings():
            # osqp 1.x warns that solve()'s raise_error default will change; qpsolvers calls it.
            warnings.simplefilter("ignore", PendingDeprecationWarning)
            solution = qpsolvers.solve_problem(problem, solver=solver, **options)
    return solution.x if solution.found and solution.x is not None else None


def check_limit_parameters(
    limit_gain: float,
    infeasible_policy: str,
    policies: Sequence[str],
    acceleration_limit: float | Sequence[float] | None,
) -> None:
    """Validate the joint-limit parameters shared by the QP backends.

    Raises:
        ParameterError: ``limit_gain`` outside (0, 1], an unknown ``infeasible_policy``, or an
            ``acceleration_limit`` that is not > 0 [rad/s²].
    """
    if not (np.isfinite(limit_gain) and 0.0 < limit_gain <= 1.0):
        raise ParameterError("limit_gain", f"must be in (0, 1], got {limit_gain}")
    if infeasible_policy not in policies:
        raise ParameterError(
            "infeasible_policy",
            f"must be one of {', '.join(policies)}, got {infeasible_policy!r}",
        )
    if acceleration_limit is not None:
        acc = np.asarray(acceleration_limit, dtype=float)
        if not np.all(acc > 0.0):
            raise ParameterError("acceleration_limit", f"must be > 0 [rad/s²], got {acc.tolist()}")


def per_joint(value: float | Sequence[float] | None, name: str, nv: int) -> FloatArray | None:
    """A scalar or ``(nv,)`` parameter as an ``(nv,)`` array (None stays None).

    Raises:
        DimensionError: ``value`` is neither a scalar nor of shape ``(nv,)``.
    """
    if value is None:
        return None
    array = np.asarray(value, dtype=float)
    if array.ndim == 0:
        array = np.full(nv, float(array))
    if array.shape != (nv,):
        raise DimensionError(name, (nv,), array.shape)
    return array


class VelocityBox(NamedTuple):
    """Per-joint boxes on ``q̇`` [rad/s], each ``(lower, upper)`` of shape ``(nv,)``.

    Attributes:
        velocity: Joint speed limits.
        position: Position limits turned into velocity bounds with gain ``g``.
        acceleration: Acceleration limits around the previous ``q̇`` (±inf when unused).
        lower: Intersection lower bound ``lb``.
        upper: Intersection upper bound ``ub``.
    """

    velocity: tuple[FloatArray, FloatArray]
    position: tuple[FloatArray, FloatArray]
    acceleration: tuple[FloatArray, FloatArray]
    lower: FloatArray
    upper: FloatArray

    @property
    def empty(self) -> bool:
        """Whether no ``q̇`` satisfies every box."""
        return bool(np.any(self.lower > self.upper))

    def conflict(self, joint_names: tuple[str, ...]) -> str:
        """One-line description of the first joint whose box is empty."""
        i = int(np.argmax(self.lower - self.upper))
        name = joint_names[i] if i < len(joint_names) else f"#{i}"
        return (
            f"joint {name!r}: velocity box [{self.velocity[0][i]:.6g}, {self.velocity[1][i]:.6g}],"
            f" position box [{self.position[0][i]:.6g}, {self.position[1][i]:.6g}],"
            f" acceleration box [{self.acceleration[0][i]:.6g}, {self.acceleration[1][i]:.6g}]"
            " do not intersect"
        )

    def relaxed(self) -> tuple[FloatArray, FloatArray]:
        r"""A non-empty box honouring the limits by priority: velocity, position, acceleration.

        Starting from the velocity box, each next box is intersected when the intersection is
        non-empty; otherwise the current box shrinks to its point nearest to that box. A joint
        beyond its position limit thus moves back as fast as its speed limit allows.
        """
        lower, upper = self.velocity[0].copy(), self.velocity[1].copy()
        for lo, hi in (self.position, self.acceleration):
            new_lower, new_upper = np.maximum(lower, lo), np.minimum(upper, hi)
            clash = new_lower > new_upper
            nearest = np.clip(np.where(hi < lower, hi, lo), lower, upper)
            lower = np.where(clash, nearest, new_lower)
            upper = np.where(clash, nearest, new_upper)
        return lower, upper


def velocity_box(
    theta: FloatArray,
    position_limits: tuple[FloatArray, FloatArray],
    velocity_limits: FloatArray,
    qdot_prev: FloatArray,
    dt: float,
    limit_gain: float,
    acceleration_limit: FloatArray | None,
) -> VelocityBox:
    r"""The joint-velocity boxes at joint coordinates ``theta``.

    .. math::
        lb = \max(-\dot q_{max},\ -g(\theta-\theta_{min})/dt,\ \dot q_{prev}-a_{max}dt),\quad
        ub = \min(\dot q_{max},\ g(\theta_{max}-\theta)/dt,\ \dot q_{prev}+a_{max}dt)

    Args:
        theta: Joint coordinates [rad or m], shape ``(nv,)``.
        position_limits: ``(θ_min, θ_max)``, shapes ``(nv,)`` (±inf allowed).
        velocity_limits: ``q̇_max`` [rad/s], shape ``(nv,)`` (inf allowed).
        qdot_prev: Previous joint velocity [rad/s], shape ``(nv,)``.
        dt: Control period [s].
        limit_gain: ``g ∈ (0, 1]``: fraction of the remaining distance allowed per step.
        acceleration_limit: ``a_max`` [rad/s²], shape ``(nv,)``, or None.
    """
    with np.errstate(invalid="ignore"):  # inf − inf cannot occur: limits are finite or ±inf
        pos_lower = (limit_gain / dt) * (position_limits[0] - theta)
        pos_upper = (limit_gain / dt) * (position_limits[1] - theta)
    vel = (-velocity_limits, velocity_limits)
    if acceleration_limit is None:
        inf = np.full(theta.shape, np.inf)
        acc = (-inf, inf)
        lower = np.maximum(vel[0], pos_lower)
        upper = np.minimum(vel[1], pos_upper)
    else:
        step = acceleration_limit * dt
        acc = (qdot_prev - step, qdot_prev + step)
        lower = np.maximum(np.maximum(vel[0], pos_lower), acc[0])
        upper = np.minimum(np.minimum(vel[1], pos_upper), acc[1])
    return VelocityBox(vel, (pos_lower, pos_upper), acc, lower, upper)


def build_qp(
    task_jacobian: FloatArray,
    xdot: FloatArray,
    damping: float,
    lower: FloatArray,
    upper: FloatArray,
    posture_weight: float = 0.0,
    posture_velocity: FloatArray | None = None,
) -> qpsolvers.Problem:
    r"""The differential-IK QP (pure function).

    .. math::
        \min_{\dot q}\ \tfrac12\|J_w\dot q - \dot x_w\|^2 + \tfrac12\lambda\|\dot q\|^2
        + \tfrac12 w_p\|\dot q - \dot q_p\|^2 \quad\text{s.t.}\quad lb \le \dot q \le ub

    i.e. ``P = J_wᵀJ_w + (λ + w_p)I``, ``q = −(J_wᵀẋ_w + w_p q̇_p)``.

    Args:
        task_jacobian: ``J_w``, shape ``(n, nv)``.
        xdot: ``ẋ_w``, shape ``(n,)``.
        damping: ``λ > 0`` [task units² per (rad/s)²].
        lower: ``lb`` [rad/s], shape ``(nv,)``; ±inf are passed as ±:data:`BIG`.
        upper: ``ub`` [rad/s], shape ``(nv,)``.
        posture_weight: ``w_p ≥ 0``.
        posture_velocity: ``q̇_p = g_p(θ_nominal − θ)`` [rad/s], shape ``(nv,)``.
    """
    nv = task_jacobian.shape[1]
    hessian = task_jacobian.T @ task_jacobian
    hessian[np.diag_indices(nv)] += damping + posture_weight
    linear = -(task_jacobian.T @ xdot)
    if posture_weight > 0.0 and posture_velocity is not None:
        linear -= posture_weight * posture_velocity
    return qpsolvers.Problem(
        hessian, linear, lb=np.clip(lower, -BIG, BIG), ub=np.clip(upper, -BIG, BIG)
    )


class BoxBuffers:
    r"""Allocation-free evaluation of :func:`velocity_box`'s ``lb``/``ub`` every step.

    The step-invariant parts (velocity limits, ``g/dt``, ``a_max·dt``) are fixed here once
    per run; :meth:`update` writes

    .. math::
        lb = \max(-\dot q_{max},\ (g/dt)(\theta_{min}-\theta),\ \dot q_{prev}-a_{max}dt),\quad
        ub = \min(\dot q_{max},\ (g/dt)(\theta_{max}-\theta),\ \dot q_{prev}+a_{max}dt)

    into one preallocated ``(2, nv)`` array with the same floating-point operations as
    :func:`velocity_box`, so both give bit-identical bounds. :meth:`margins` gives the
    signed distances to both bounds in one pass.

    Args:
        position_limits: ``(θ_min, θ_max)``, shapes ``(nv,)`` (±inf allowed).
        velocity_limits: ``q̇_max`` [rad/s], shape ``(nv,)`` (inf allowed).
        dt: Control period [s].
        limit_gain: ``g ∈ (0, 1]``.
        acceleration_limit: ``a_max`` [rad/s²], shape ``(nv,)``, or None.

    Attributes:
        bounds: ``[lb, ub]`` [rad/s] of the last :meth:`update`, shape ``(2, nv)``
            (overwritten by every update).
        lower: View ``bounds[0]``.
        upper: View ``bounds[1]``.
    """

    def __init__(
        self,
        position_limits: tuple[FloatArray, FloatArray],
        velocity_limits: FloatArray,
        dt: float,
        limit_gain: float,
        acceleration_limit: FloatArray | None,
    ) -> None:
        nv = velocity_limits.shape[0]
        self._theta_limits = np.array(position_limits, dtype=float).reshape(2, nv)
        speeds = np.array(velocity_limits, dtype=float)
        self._vel_lower = -speeds
        self._vel_upper = speeds
        self._gain = limit_gain / dt  # [1/s]
        self._acc_step = None if acceleration_limit is None else acceleration_limit * dt
        self.bounds = np.empty((2, nv))
        self.lower = self.bounds[0]
        self.upper = self.bounds[1]
        self._scratch = np.empty((2, nv))
        self._threshold = np.empty((2, nv))
        self._mask = np.empty((2, nv), dtype=bool)
        self._signs = np.array([[1.0], [-1.0]])

    def update(self, theta: FloatArray, qdot_prev: FloatArray) -> bool:
        """Write ``lb``, ``ub`` for joint coordinates ``theta`` (nv,); True if the box is empty."""
        lower, upper, scratch = self.lower, self.upper, self._scratch
        np.subtract(self._theta_limits, theta, out=scratch)
        np.multiply(self._gain, scratch, out=scratch)  # position boxes, (2, nv)
        np.maximum(self._vel_lower, scratch[0], out=lower)
        np.minimum(self._vel_upper, scratch[1], out=upper)
        if self._acc_step is not None:
            np.subtract(qdot_prev, self._acc_step, out=scratch[0])
            np.maximum(lower, scratch[0], out=lower)
            np.add(qdot_prev, self._acc_step, out=scratch[1])
            np.minimum(upper, scratch[1], out=upper)
        return bool(np.greater(lower, upper, out=self._mask[0]).any())

    def margins(self, qdot: FloatArray) -> FloatArray:
        """``[q̇ − lb, ub − q̇]`` [rad/s], shape ``(2, nv)`` (overwritten by the next call).

        Every entry is ``≥ 0`` exactly when ``lb ≤ q̇ ≤ ub`` (IEEE subtraction keeps the sign);
        a NaN in ``q̇`` gives NaN margins.
        """
        margins = self._scratch
        np.subtract(qdot, self.bounds, out=margins)
        np.multiply(self._signs, margins, out=margins)
        return margins

    def any_active(self, margins: FloatArray, tol: float) -> bool:
        """Whether some margin is ``≤ tol·(1 + |bound|)`` (a bound active within ``tol``)."""
        threshold = self._threshold
        np.abs(self.bounds, out=threshold)
        np.add(1.0, threshold, out=threshold)
        np.multiply(tol, threshold, out=threshold)
        return bool(np.less_equal(margins, threshold, out=self._mask).any())
