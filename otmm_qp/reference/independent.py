r"""A second method for the min-max, to check the reference's upper bound independently.

scipy's SLSQP on the epigraph form over joint *knots*: every ``stride``-th sample (and the
last) is a variable, the samples between are linearly interpolated, ``q_0`` is fixed:

.. math:: \min_{Q_{knots}, t} t \quad\text{s.t.}\quad t - m_k(q_k) \ge 0\ (k \ge 1),\quad
          s\,(j_{i+1} - j_i) - |Q_{i+1} - Q_i| \ge 0,\quad l \le Q_i \le u

(``s = v_max dt``: a linear segment over ``j_{i+1} − j_i`` samples moves evenly, so every
sample step is within the limit; the box holds between knots by convexity). The gradients of
``m_k = max(‖e_pos‖/tol_pos, ‖e_rot‖/tol_rot)`` are the active part's
``−J_pᵀ e_p/(‖e_p‖ tol_p)`` through the interpolation weights. A restricted path class, so
its merit is an upper bound too: if it beats the reference's ``upper`` by much, the reference
is not optimal. Dense and slow: for sampled tasks only (``benchmarks/bench_reference.py
--check``, ``tests/reference/test_bracket.py``).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.reference.projection import project_path
from otmm_qp.robots.robot import FloatArray


def _weights(count: int, stride: int) -> tuple[np.ndarray, FloatArray]:
    """Knot samples ``(K,)`` and the interpolation matrix ``W`` ``(N, K)`` (``q = W Q``)."""
    knots = np.unique(np.r_[np.arange(0, count, stride), count - 1])
    weights = np.zeros((count, knots.size))
    for k in range(count):
        i = min(int(np.searchsorted(knots, k, side="right")) - 1, knots.size - 2)
        i = max(i, 0)
        span = knots[i + 1] - knots[i] if knots.size > 1 else 1
        w = (k - knots[i]) / span if knots.size > 1 else 0.0
        weights[k, i] += 1.0 - w
        if knots.size > 1:
            weights[k, i + 1] += w
    return knots, weights


def slsqp_upper(
    problem: TrackingProblem, start: FloatArray, stride: int = 1, iterations: int = 200
) -> float:
    """``max_k m_k`` of the SLSQP solution from ``start`` ``(N, nv)``, made feasible exactly.

    Args:
        problem: The task.
        start: Initial path ``(N, nv)`` (sampled at the knots).
        stride: Samples per knot (1: every sample is a variable).
        iterations: SLSQP iteration cap.

    Returns:
        The merit [tolerances] of the (projected) path SLSQP ends at.
    """
    nv, count, robot = problem.nv, problem.samples, problem.robot
    if count < 2:
        return float(np.max(problem.merits(problem.errors(start))))
    knots, weights = _weights(count, stride)
    free = knots.size - 1  # knot 0 is q_0
    settings = problem.settings
    parts = []
    if settings.position_tolerance is not None:
        parts.append((slice(0, problem.linear), settings.position_tolerance))
    if problem.pose and settings.orientation_tolerance is not None:
        parts.append((slice(3, 6), settings.orientation_tolerance))

    def path_of(z: FloatArray) -> FloatArray:
        values = np.vstack([problem.q0, z[:-1].reshape(free, nv)])
        return np.asarray(weights @ values, dtype=float)

    def merit_and_gradient(z: FloatArray) -> tuple[FloatArray, FloatArray]:
        path = path_of(z)
        merits = np.zeros(count - 1)
        gradient = np.zeros((count - 1, z.size))
        for k in range(1, count):
            x, jacobian = robot.kinematics(robot.configuration(path[k]))
            error = robot.task_error(problem.targets[k], x)
            best, grad = -1.0, np.zeros(nv)
            for rows, tolerance in parts:
                size = float(np.linalg.norm(error[rows]))
                if size / tolerance > best:
                    best = size / tolerance
                    grad = -(jacobian[rows].T @ error[rows]) / (max(size, 1e-15) * tolerance)
            merits[k - 1] = best
            row = np.outer(weights[k, 1:], grad).ravel()  # d m_k / d Q (knots 1..)
            gradient[k - 1, :-1] = -row
            gradient[k - 1, -1] = 1.0
        return merits, gradient

    span = np.diff(knots).astype(float)
    step = np.minimum(problem.step, 1e9)
    difference = np.zeros((free * nv, z_size := free * nv + 1))
    for i in range(free):
        for j in range(nv):
            difference[i * nv + j, i * nv + j] = 1.0
            if i > 0:
                difference[i * nv + j, (i - 1) * nv + j] = -1.0
    limit = (span[:, None] * step[None, :]).ravel()

    def moves(z: FloatArray) -> FloatArray:
        values = np.vstack([problem.q0, z[:-1].reshape(free, nv)])
        return np.asarray(np.diff(values, axis=0).ravel(), dtype=float)

    constraints = [
        {
            "type": "ineq",
            "fun": lambda z: z[-1] - merit_and_gradient(z)[0],
            "jac": lambda z: merit_and_gradient(z)[1],
        },
        {"type": "ineq", "fun": lambda z: limit - moves(z), "jac": lambda z: -difference},
        {"type": "ineq", "fun": lambda z: limit + moves(z), "jac": lambda z: difference},
    ]
    box = [
        (float(lo) if np.isfinite(lo) else None, float(hi) if np.isfinite(hi) else None)
        for lo, hi in zip(problem.lower, problem.upper, strict=True)
    ]
    bounds: list[tuple[float | None, float | None]] = [*(box * free), (0.0, None)]
    z0 = np.concatenate([np.asarray(start, dtype=float)[knots[1:]].ravel(), [0.0]])
    z0[:-1] = np.clip(
        z0[:-1], np.tile(problem.lower, free), np.tile(problem.upper, free)
    )  # knots inside the box
    z0[-1] = float(np.max(merit_and_gradient(z0)[0]))
    unit = np.zeros(z_size)
    unit[-1] = 1.0
    solution = minimize(
        lambda z: z[-1],
        z0,
        jac=lambda z: unit,
        method="SLSQP",
        bounds=bounds,
        constraints=constraints,
        options={"maxiter": iterations, "ftol": 1e-10},
    )
    path = project_path(path_of(np.asarray(solution.x)), problem.lower, problem.upper, problem.step)
    return float(np.max(problem.merits(problem.errors(path))))
