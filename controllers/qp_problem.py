r"""The QP differential-IK formulation, pure: joint-velocity boxes and the QP data.

Every joint limit of the velocity-level problem is a box on ``q̇`` (shape ``(nv,)``):

.. math::
    \underbrace{-\dot q_{max}}_{\text{velocity}} \le \dot q \le \dot q_{max},\qquad
    \underbrace{-g\frac{\theta - \theta_{min}}{dt}}_{\text{position}} \le \dot q \le
    g\frac{\theta_{max} - \theta}{dt},\qquad
    \underbrace{\dot q_{prev} - a_{max}dt}_{\text{acceleration}} \le \dot q \le
    \dot q_{prev} + a_{max}dt

so the feasible set is their intersection ``[lb, ub]`` and it is empty exactly when some
``lb_i > ub_i`` (e.g. a start outside the position limits farther than ``v_max·dt/g``).

Each equation is written once. :func:`velocity_bounds` and :func:`build_qp` take an optional
``out=`` to write into preallocated arrays (the per-step path of the backends); without it
they allocate (the reference path). Building is kept apart from solving
(:mod:`otmm_qp_controllers.qp_solvers`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from otmm_qp.exceptions import DimensionError, ParameterError
from otmm_qp.robots.robot import FloatArray
from otmm_qp_controllers.qp_solvers.problem import BIG, QpProblem
from otmm_qp_controllers.qp_solvers.qpsolvers_session import SOLVER_OPTIONS

__all__ = [
    "BIG",
    "SOLVER_OPTIONS",
    "JointLimits",
    "QpProblem",
    "VelocityBox",
    "active_bound",
    "build_qp",
    "check_limit_parameters",
    "clip_into_box",
    "per_joint",
    "velocity_bounds",
    "velocity_box",
]


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


class JointLimits(NamedTuple):
    """The step-invariant joint-limit data of one run.

    Attributes:
        theta: ``[θ_min; θ_max]`` [rad or m], shape ``(2, nv)`` (±inf allowed).
        speed: ``q̇_max`` [rad/s], shape ``(nv,)`` (inf allowed).
        negative_speed: ``−q̇_max`` [rad/s], shape ``(nv,)``.
        gain: ``g/dt`` [1/s], the position-limit gain per control period.
        acceleration_step: ``a_max·dt`` [rad/s], shape ``(nv,)``, or None (no limit).
    """

    theta: FloatArray
    speed: FloatArray
    negative_speed: FloatArray
    gain: float
    acceleration_step: FloatArray | None

    @classmethod
    def make(
        cls,
        position_limits: tuple[FloatArray, FloatArray],
        velocity_limits: FloatArray,
        dt: float,
        limit_gain: float,
        acceleration_limit: FloatArray | None,
    ) -> JointLimits:
        """From the robot's limits, ``dt`` [s], ``g ∈ (0, 1]`` and ``a_max`` [rad/s²] or None."""
        speed = np.array(velocity_limits, dtype=float)
        theta = np.array(position_limits, dtype=float).reshape(2, speed.shape[0])
        step = None if acceleration_limit is None else acceleration_limit * dt
        return cls(theta, speed, -speed, limit_gain / dt, step)


def position_box(theta: FloatArray, limits: JointLimits, out: FloatArray) -> FloatArray:
    r"""``[(g/dt)(θ_min − θ); (g/dt)(θ_max − θ)]`` [rad/s] into ``out`` (2, nv).

    Infinite limits give infinite bounds (θ is finite, ``g/dt > 0``: no NaN can arise).
    """
    np.subtract(limits.theta, theta, out=out)
    return np.multiply(limits.gain, out, out=out)


def velocity_bounds(
    theta: FloatArray,
    qdot_prev: FloatArray,
    limits: JointLimits,
    out: FloatArray | None = None,
    scratch: FloatArray | None = None,
) -> FloatArray:
    r"""The intersection ``[lb; ub]`` of the velocity, position and acceleration boxes.

    .. math::
        lb = \max(-\dot q_{max},\ (g/dt)(\theta_{min}-\theta),\ \dot q_{prev}-a_{max}dt),\quad
        ub = \min(\dot q_{max},\ (g/dt)(\theta_{max}-\theta),\ \dot q_{prev}+a_{max}dt)

    Args:
        theta: Joint coordinates [rad or m], shape ``(nv,)``.
        qdot_prev: Previous joint velocity [rad/s], shape ``(nv,)``.
        limits: The run's :class:`JointLimits`.
        out: Where to write ``[lb; ub]``, shape ``(2, nv)``; allocated when None.
        scratch: Work array of shape ``(2, nv)``; allocated when None.

    Returns:
        ``out`` [rad/s], shape ``(2, nv)``.
    """
    nv = limits.speed.shape[0]
    out = np.empty((2, nv)) if out is None else out
    scratch = np.empty((2, nv)) if scratch is None else scratch
    lower, upper = out[0], out[1]
    position_box(theta, limits, scratch)
    np.maximum(limits.negative_speed, scratch[0], out=lower)
    np.minimum(limits.speed, scratch[1], out=upper)
    if limits.acceleration_step is not None:
        np.subtract(qdot_prev, limits.acceleration_step, out=scratch[0])
        np.maximum(lower, scratch[0], out=lower)
        np.add(qdot_prev, limits.acceleration_step, out=scratch[1])
        np.minimum(upper, scratch[1], out=upper)
    return out


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
    r"""Every joint-velocity box at joint coordinates ``theta`` (pure; see :func:`velocity_bounds`).

    Args:
        theta: Joint coordinates [rad or m], shape ``(nv,)``.
        position_limits: ``(θ_min, θ_max)``, shapes ``(nv,)`` (±inf allowed).
        velocity_limits: ``q̇_max`` [rad/s], shape ``(nv,)`` (inf allowed).
        qdot_prev: Previous joint velocity [rad/s], shape ``(nv,)``.
        dt: Control period [s].
        limit_gain: ``g ∈ (0, 1]``: fraction of the remaining distance allowed per step.
        acceleration_limit: ``a_max`` [rad/s²], shape ``(nv,)``, or None.
    """
    limits = JointLimits.make(position_limits, velocity_limits, dt, limit_gain, acceleration_limit)
    bounds = velocity_bounds(theta, qdot_prev, limits)
    position = position_box(theta, limits, np.empty_like(bounds))
    if limits.acceleration_step is None:
        inf = np.full(theta.shape, np.inf)
        acceleration = (-inf, inf)
    else:
        step = limits.acceleration_step
        acceleration = (qdot_prev - step, qdot_prev + step)
    velocity = (limits.negative_speed, limits.speed)
    return VelocityBox(velocity, (position[0], position[1]), acceleration, bounds[0], bounds[1])


def active_bound(qdot: FloatArray, bounds: FloatArray, tol: float) -> bool | None:
    r"""Whether some :math:`\dot q_i` is within ``tol·(1 + |bound|)`` of ``lb_i`` or ``ub_i``.

    .. math:: \exists i:\ \dot q_i - lb_i \le \tau(1 + |lb_i|)\ \lor\
              ub_i - \dot q_i \le \tau(1 + |ub_i|)

    for finite bounds (an infinite one is never active).

    Args:
        qdot: Joint velocity [rad/s], shape ``(nv,)``.
        bounds: ``[lb; ub]`` [rad/s], shape ``(2, nv)``.
        tol: Relative tolerance τ [-].

    Returns:
        The answer, or None when ``qdot`` lies outside the box (or is NaN): one pass serves the
        QP's fast path (inside?) and the status (active?).
    """
    # A scalar loop: for an arm's nv ≤ ~10 joints it costs a third of the eight NumPy calls
    # (each ~1 µs) that the array form needs, and this runs on every QP step.
    active = False
    lower, upper = bounds.tolist()
    for value, low, high in zip(qdot.tolist(), lower, upper, strict=True):
        if not low <= value <= high:  # also for NaN
            return None
        # An infinite bound is never active (inf ≤ τ(1 + inf) would say it is).
        if (value - low <= tol * (1.0 + abs(low)) and low != -math.inf) or (
            high - value <= tol * (1.0 + abs(high)) and high != math.inf
        ):
            active = True
    return active


def clip_into_box(x: FloatArray, bounds: FloatArray, tol: float) -> tuple[FloatArray, bool] | None:
    r"""A solver's answer clipped into the box, and whether a bound is then active.

    .. math:: \dot q = \min(\max(x, lb), ub),\qquad
              \text{active} = \text{active\_bound}(\dot q, [lb; ub], \tau)

    for a non-empty box (``lb ≤ ub``); clipping removes the solver's tolerance, so a returned
    ``q̇`` never violates a bound.

    Args:
        x: The solver's primal solution [rad/s], shape ``(nv,)``.
        bounds: ``[lb; ub]`` [rad/s], shape ``(2, nv)``, ``lb ≤ ub``.
        tol: Relative tolerance τ [-] of :func:`active_bound`.

    Returns:
        ``(q̇ (nv,) a new array, active)``, or None when some ``x_i`` is NaN or ±inf.
    """
    # One scalar pass instead of isfinite/all, maximum/minimum and active_bound's pass (the
    # every-step QP path runs this on each step; see active_bound for why scalar).
    values = x.tolist()
    if not math.isfinite(sum(values)):  # NaN or ±inf somewhere (or entries beyond 1e308)
        return None
    active = False
    lower, upper = bounds.tolist()
    for i, (value, low, high) in enumerate(zip(values, lower, upper, strict=True)):
        if value <= low:
            values[i] = low
            active = active or low != -math.inf
        elif value >= high:
            values[i] = high
            active = active or high != math.inf
        elif not active and (
            (value - low <= tol * (1.0 + abs(low)) and low != -math.inf)
            or (high - value <= tol * (1.0 + abs(high)) and high != math.inf)
        ):
            active = True
    return np.array(values), active


def build_qp(
    task_jacobian: FloatArray,
    xdot: FloatArray,
    damping: float,
    bounds: FloatArray | None,
    posture_weight: float = 0.0,
    posture_velocity: FloatArray | None = None,
    out: QpProblem | None = None,
) -> QpProblem:
    r"""The differential-IK QP.

    .. math::
        \min_{\dot q}\ \tfrac12\|J_w\dot q - \dot x_w\|^2 + \tfrac12\mu\|\dot q\|^2
        + \tfrac12 w_p\|\dot q - \dot q_p\|^2 \quad\text{s.t.}\quad lb \le \dot q \le ub

    i.e. ``P = J_wᵀJ_w + (μ + w_p)I``, ``q = −(J_wᵀẋ_w + w_p q̇_p)``; ``±inf`` bounds are
    passed as ``±BIG``. The general-constraint rows of ``out`` (e.g. the singularity barrier)
    are left untouched.

    Args:
        task_jacobian: ``J_w``, shape ``(n, nv)``.
        xdot: ``ẋ_w``, shape ``(n,)``.
        damping: ``μ = λ² > 0`` [task units² per (rad/s)²].
        bounds: ``[lb; ub]`` [rad/s], shape ``(2, nv)``; None when ``out.lb``, ``out.ub``
            already hold the box within ``±BIG`` (a backend whose box is written into the
            problem, :meth:`QpProblem.allocate` with ``box=``).
        posture_weight: ``w_p ≥ 0``.
        posture_velocity: ``q̇_p = g_p(θ_nominal − θ)`` [rad/s], shape ``(nv,)``.
        out: Problem whose ``P``, ``q``, ``lb``, ``ub`` are overwritten; a new box-only
            problem when None.

    Raises:
        ParameterError: ``bounds`` is None without ``out``.
    """
    nv = task_jacobian.shape[1]
    if out is None:
        if bounds is None:
            raise ParameterError("bounds", "None needs out= holding the box")
        out = QpProblem.allocate(nv)
    hessian, linear = out.P, out.q
    # ndarray.dot rather than matmul or np.dot: the least call overhead on arm-sized arrays.
    task_jacobian.T.dot(task_jacobian, out=hessian)
    diagonal = hessian.reshape(-1)[:: nv + 1]  # a view on the diagonal
    np.add(diagonal, damping + posture_weight, out=diagonal)
    xdot.dot(task_jacobian, out=linear)
    np.negative(linear, out=linear)
    if posture_weight > 0.0 and posture_velocity is not None:
        linear -= posture_weight * posture_velocity
    if bounds is not None:
        np.minimum(np.maximum(bounds[0], -BIG, out=out.lb), BIG, out=out.lb)
        np.minimum(np.maximum(bounds[1], -BIG, out=out.ub), BIG, out=out.ub)
    return out
