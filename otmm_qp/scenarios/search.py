r"""Configuration search shared by the generators: random samples, σ_min descent, damped IK."""

from __future__ import annotations

import numpy as np

from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.singularity import sigma_min_gradient
from otmm_qp.state import KinematicState

#: Range [rad] used for joints without position limits.
UNBOUNDED_RANGE = np.pi


def sampling_bounds(robot: Robot, margin: float = 0.0) -> tuple[FloatArray, FloatArray]:
    """Finite joint-coordinate bounds ``(lower, upper)``, shapes ``(nv,)``, shrunk by ``margin``.

    Unbounded joints get ``[−π, π]``; ``margin`` [rad] keeps samples off the limits.
    """
    lower, upper = robot.position_limits
    lower = np.where(np.isfinite(lower), lower, -UNBOUNDED_RANGE)
    upper = np.where(np.isfinite(upper), upper, UNBOUNDED_RANGE)
    shrink = np.minimum(margin, 0.25 * (upper - lower))
    return lower + shrink, upper - shrink


def random_coordinates(robot: Robot, rng: np.random.Generator, margin: float = 0.05) -> FloatArray:
    """Uniform joint coordinates inside the (shrunk) limits, shape ``(nv,)``."""
    lower, upper = sampling_bounds(robot, margin)
    return np.asarray(rng.uniform(lower, upper), dtype=float)


def clip_coordinates(robot: Robot, coordinates: FloatArray) -> FloatArray:
    """Joint coordinates clipped into the position limits, shape ``(nv,)``."""
    lower, upper = robot.position_limits
    return np.asarray(np.clip(coordinates, lower, upper), dtype=float)


def sigma_min_at(robot: Robot, coordinates: FloatArray, weight: FloatArray | None = None) -> float:
    """σ_min of the weighted task Jacobian at joint coordinates ``(nv,)``."""
    return KinematicState.compute(robot, robot.configuration(coordinates), weight).sigma_min


def descend_sigma_min(
    robot: Robot,
    coordinates: FloatArray,
    tolerance: float,
    iterations: int,
    weight: FloatArray | None = None,
    max_step: float = 0.3,
) -> FloatArray | None:
    r"""Drive σ_min to below ``tolerance`` from ``coordinates`` by Newton steps on σ_min = 0.

    .. math:: q \leftarrow \Pi\!\left(q - \frac{\sigma_{min}}{\|\nabla\sigma_{min}\|^2}
              \nabla\sigma_{min}\right)

    (step norm capped at ``max_step`` [rad], :math:`\Pi` = clip into the limits).

    Returns:
        Joint coordinates with σ_min < ``tolerance``, or None when ``iterations`` ran out.
    """
    q = clip_coordinates(robot, np.asarray(coordinates, dtype=float))
    for _ in range(iterations):
        state = KinematicState.compute(robot, robot.configuration(q), weight)
        sigma = state.sigma_min
        if sigma < tolerance:
            return q
        gradient = sigma_min_gradient(robot, state)
        norm2 = float(gradient @ gradient)
        if not norm2 > 1e-24:
            return None
        step = (sigma / norm2) * gradient
        length = float(np.linalg.norm(step))
        if length > max_step:
            step *= max_step / length
        q = clip_coordinates(robot, q - step)
    return None


class _Reached(Exception):
    """σ_min fell below the tolerance: stop the minimiser (carries nothing; the best is kept)."""


def minimise_sigma_min(
    robot: Robot,
    coordinates: FloatArray,
    tolerance: float,
    iterations: int,
    weight: FloatArray | None = None,
) -> FloatArray | None:
    r"""Minimise σ_min of the task Jacobian inside the joint limits, from ``coordinates``.

    .. math:: \min_{q}\ \sigma_{min}(W J(q)) \quad	ext{s.t.}\quad q_{lo} \le q \le q_{hi}

    by L-BFGS-B with the analytic gradient (:func:`~otmm_qp.singularity.sigma_min_gradient`),
    stopped as soon as σ_min < ``tolerance``. Unlike :func:`descend_sigma_min` (Newton steps on
    σ_min = 0, clipped into the limits) it follows the limits: a 7-DoF arm's position Jacobian
    is singular only where several joints sit at or near a limit (the Panda's stretched
    elbow), which the clipped Newton steps do not reach.

    Returns:
        Joint coordinates ``(nv,)`` with σ_min < ``tolerance``, or None after ``iterations``.
    """
    from scipy.optimize import minimize

    lower, upper = sampling_bounds(robot)
    found: list[FloatArray] = []

    def value_and_gradient(q: FloatArray) -> tuple[float, FloatArray]:
        state = KinematicState.compute(robot, robot.configuration(q), weight)
        if state.sigma_min < tolerance:
            found.append(np.array(q, dtype=float))
            raise _Reached
        return state.sigma_min, sigma_min_gradient(robot, state)

    start = np.clip(np.asarray(coordinates, dtype=float), lower, upper)
    try:
        minimize(
            value_and_gradient,
            start,
            jac=True,
            bounds=list(zip(lower, upper, strict=True)),
            method="L-BFGS-B",
            options={"maxiter": iterations},
        )
    except _Reached:
        return found[-1]
    return None


def solve_ik(
    robot: Robot,
    coordinates: FloatArray,
    target: FloatArray,
    position_only: bool = False,
    tolerance: float = 1e-6,
    iterations: int = 200,
    damping: float = 1e-3,
    max_step: float = 0.3,
) -> FloatArray | None:
    r"""Damped Newton inverse kinematics from ``coordinates`` to ``target``, inside the limits.

    .. math:: \Delta q = J^\top (J J^\top + \lambda^2 I)^{-1} e(x^*, x)

    Args:
        robot: The arm.
        coordinates: Initial joint coordinates, shape ``(nv,)``.
        target: Target task value (point or ``(4, 4)`` pose).
        position_only: Match only the position rows of a pose task (orientation free).
        tolerance: Stop when ‖e‖ < tolerance [task units].
        iterations: Iteration budget.
        damping: λ [task units].
        max_step: Cap on ‖Δq‖ [rad].

    Returns:
        Joint coordinates reaching the target, or None.
    """
    q = clip_coordinates(robot, np.asarray(coordinates, dtype=float))
    rows = slice(0, 3) if position_only and robot.task_kind == "pose" else slice(None)
    for _ in range(iterations):
        x, jacobian = robot.kinematics(robot.configuration(q))
        error = robot.task_error(target, x)[rows]
        if float(np.linalg.norm(error)) < tolerance:
            return q
        J = jacobian[rows]
        step = J.T @ np.linalg.solve(J @ J.T + damping**2 * np.eye(J.shape[0]), error)
        length = float(np.linalg.norm(step))
        if length > max_step:
            step *= max_step / length
        q = clip_coordinates(robot, q + step)
    return None


def position_of(x: FloatArray) -> FloatArray:
    """Position part of a task value (a point, or a pose's translation)."""
    value = np.asarray(x, dtype=float)
    return value[:3, 3].copy() if value.ndim == 2 else value.copy()


def with_position(x: FloatArray, position: FloatArray) -> FloatArray:
    """Task value ``x`` moved to ``position`` (a pose keeps its orientation)."""
    value = np.array(x, dtype=float, copy=True)
    if value.ndim == 2:
        value[:3, 3] = position
        return value
    return np.asarray(position, dtype=float).copy()


def base_position(robot: Robot) -> FloatArray:
    """Origin of the arm's first joint [m] (origin for planar arms), shape ``(d,)``."""
    base = getattr(robot, "_base", None)
    if base is not None:
        return np.asarray(base, dtype=float).copy()
    return np.zeros(3 if robot.task_kind == "pose" else robot.task_dim)


def reach_radius(robot: Robot) -> float:
    """Upper bound of the distance from :func:`base_position` any configuration reaches [m]."""
    for attribute in ("reach", "reach_max"):
        value = getattr(robot, attribute, None)
        if value is not None:
            return float(value)
    rng = np.random.default_rng(0)
    base = base_position(robot)
    samples = (random_coordinates(robot, rng, 0.0) for _ in range(512))
    return max(
        float(np.linalg.norm(position_of(robot.forward(robot.configuration(q))) - base))
        for q in samples
    )
