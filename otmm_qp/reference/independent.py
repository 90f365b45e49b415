r"""A second method for the min-max, to check the reference's upper bound independently.

scipy's SLSQP on the epigraph form over the joint knots ``z = (q_1, …, q_{N−1}, t)``:

.. math:: \min_z t \quad\text{s.t.}\quad t - m_k(q_k) \ge 0,\quad
          v_{max} dt - |q_k - q_{k-1}| \ge 0,\quad l \le q_k \le u,

with finite-difference gradients (no Jacobian of the project's, no shared code with
:mod:`otmm_qp.reference.epigraph` but the merit). Dense and slow: for sampled tasks only
(``benchmarks/bench_reference.py --check``, ``tests/test_reference_bracket.py``).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.reference.projection import project_path
from otmm_qp.robots.robot import FloatArray


def slsqp_upper(problem: TrackingProblem, start: FloatArray, iterations: int = 200) -> float:
    """``max_k m_k`` of the SLSQP solution from ``start`` ``(N, nv)``, made feasible exactly.

    Returns:
        The merit [tolerances] of the (projected) path SLSQP ends at.
    """
    nv, count = problem.nv, problem.samples
    step = problem.step
    if count < 2:
        return float(np.max(problem.merits(problem.errors(start))))

    def unpack(z: FloatArray) -> FloatArray:
        return np.vstack([problem.q0, z[:-1].reshape(count - 1, nv)])

    def merits(z: FloatArray) -> FloatArray:
        return problem.merits(problem.errors(unpack(z)))

    z0 = np.concatenate([np.asarray(start[1:], dtype=float).ravel(), [0.0]])
    z0[-1] = float(np.max(merits(z0)))
    constraints = [
        {"type": "ineq", "fun": lambda z: z[-1] - merits(z)[1:]},
        {
            "type": "ineq",
            "fun": lambda z: (np.minimum(step, 1e9) - np.abs(np.diff(unpack(z), axis=0))).ravel(),
        },
    ]
    box = [
        (float(lo) if np.isfinite(lo) else None, float(hi) if np.isfinite(hi) else None)
        for lo, hi in zip(problem.lower, problem.upper, strict=True)
    ]
    bounds: list[tuple[float | None, float | None]] = [*(box * (count - 1)), (0.0, None)]
    solution = minimize(
        lambda z: z[-1],
        z0,
        jac=lambda z: np.eye(1, z.size, z.size - 1).ravel(),
        method="SLSQP",
        bounds=bounds,
        constraints=constraints,
        options={"maxiter": iterations, "ftol": 1e-10},
    )
    path = project_path(unpack(np.asarray(solution.x)), problem.lower, problem.upper, step)
    return float(np.max(problem.merits(problem.errors(path))))
