r"""Sequential convex QPs over the whole path: a trust-region Newton method with OSQP.

Each iteration solves, for the step ``δ = (δ_1, …, δ_{N−1})`` (``δ_0 = 0``: the start is
fixed),

.. math::
    \min_\delta \sum_{k=1}^{N-1} \omega_k\big(\tfrac12 \delta_k^\top [H_k]_+ \delta_k
        + g_k^\top \delta_k\big)
    \quad\text{s.t.}\quad
    \max(l - q_k, -\Delta) \le \delta_k \le \min(u - q_k, \Delta),\quad
    |q_k + \delta_k - q_{k-1} - \delta_{k-1}| \le s

(``[H]_+``: eigenvalues clipped to ``≥ ε``, ``Δ`` the trust radius [rad]). The constraint
matrix ``A = [I; D]`` (``D`` the block bidiagonal difference) and the block-diagonal pattern
of ``P`` never change, so one OSQP workspace is set up per task and only its numbers are
updated, warm-started from the previous step. A step is accepted when the true weighted
least squares decreases (ratio test on the model's prediction); ``Δ`` grows after good steps
and shrinks after bad ones.
"""

from __future__ import annotations

import time

import numpy as np
import osqp
import scipy.sparse as sp

from otmm_qp.interrupt import solve_held
from otmm_qp.reference.problem import BIG, TrackingProblem
from otmm_qp.reference.projection import project_path
from otmm_qp.robots.robot import FloatArray

#: Floor of the Hessian blocks' eigenvalues (relative to 1 + the largest one).
EIGEN_FLOOR = 1e-9
#: Stop when the model predicts less decrease than this fraction of the objective, plus
#: an absolute floor (objective units: squared tolerances; 1e-12 ≈ errors of 1e-6 tolerance).
RELATIVE_DECREASE = 1e-7
ABSOLUTE_DECREASE = 1e-12
#: Iterations allowed once a path meets every tolerance (it only sharpens the errors).
AFTER_CERTIFICATE = 1
#: Initial and smallest trust radius [rad].
INITIAL_RADIUS = 0.3
MIN_RADIUS = 1e-9
#: OSQP settings. Moderate tolerances suffice: every step is checked on the true error.
#: No polishing (it prints to stdout even when not verbose).
OSQP_SETTINGS = {
    "verbose": False,
    "eps_abs": 1e-4,
    "eps_rel": 1e-4,
    "max_iter": 100,
    "polishing": False,
    "warm_starting": True,
}


class SolverFailure(Exception):
    """OSQP refused or failed a subproblem (carried as the reference's ``failed`` state)."""


class TimeBudgetExceeded(Exception):
    """The solve ran past its time budget."""


def _upper_pattern(blocks: int, nv: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """CSC pattern of a block-diagonal upper triangle and the (row, col) of each entry.

    Returns:
        ``(indptr, indices, block_rows, block_cols)``; ``block_rows/cols`` index one
        ``(nv, nv)`` block in the data order of every block.
    """
    rows = np.array([i for j in range(nv) for i in range(j + 1)])
    cols = np.array([j for j in range(nv) for _ in range(j + 1)])
    indices = (np.arange(blocks)[:, None] * nv + rows[None, :]).ravel()
    counts = np.tile(np.arange(1, nv + 1), blocks)
    indptr = np.concatenate([[0], np.cumsum(counts)])
    return indptr, indices, rows, cols


class SequentialQP:
    """Persistent OSQP workspace for one task's path optimisation.

    Args:
        problem: The task's tracking problem (``N ≥ 2`` samples).
    """

    def __init__(self, problem: TrackingProblem) -> None:
        self.problem = problem
        self.blocks = problem.samples - 1
        nv = problem.nv
        size = self.blocks * nv
        indptr, indices, self._rows, self._cols = _upper_pattern(self.blocks, nv)
        self._indptr, self._indices = indptr, indices
        identity = sp.identity(size, format="csc")
        difference = sp.identity(size, format="csc") - sp.eye(size, size, k=-nv, format="csc")
        self.A = sp.vstack([identity, difference], format="csc")
        self.solver: osqp.OSQP | None = None
        self.radius = INITIAL_RADIUS

    def _model(self, hessians: FloatArray, weights: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Weighted positive-definite blocks ``ω_k [H_k]_+`` ``(N−1, nv, nv)`` and ``P``'s data."""
        values, vectors = np.linalg.eigh(hessians)  # (B, nv), (B, nv, nv)
        floor = EIGEN_FLOOR * (1.0 + np.max(np.abs(values), axis=1, keepdims=True))
        values = np.maximum(values, floor)
        fixed = np.einsum("bij,bj,bkj->bik", vectors, values, vectors)
        fixed *= weights[:, None, None]
        return fixed, np.asarray(fixed[:, self._rows, self._cols].ravel(), dtype=float)

    def _bounds(self, path: FloatArray) -> tuple[FloatArray, FloatArray]:
        """QP bounds ``l ≤ Aδ ≤ u`` at ``path`` with the current trust radius."""
        problem = self.problem
        current = path[1:]
        box_lo = np.maximum(problem.lower - current, -self.radius)
        box_hi = np.minimum(problem.upper - current, self.radius)
        moves = np.diff(path, axis=0)  # (N−1, nv): q_k − q_{k−1}
        step = np.minimum(problem.step, BIG)
        rate_lo = -step - moves
        rate_hi = step - moves
        # The current path is feasible, so δ = 0 is; rounding may not keep l ≤ 0 ≤ u.
        lower = np.minimum(np.concatenate([box_lo.ravel(), rate_lo.ravel()]), 0.0)
        upper = np.maximum(np.concatenate([box_hi.ravel(), rate_hi.ravel()]), 0.0)
        return lower, upper

    def _solve(
        self, data: FloatArray, gradient: FloatArray, lower: FloatArray, upper: FloatArray
    ) -> FloatArray:
        """One QP; the step ``δ`` flat ``((N−1)·nv,)``.

        Raises:
            SolverFailure: OSQP returned no finite step or an error status.
        """
        size = gradient.size
        try:
            if self.solver is None:
                P = sp.csc_matrix((data, self._indices, self._indptr), shape=(size, size))
                self.solver = osqp.OSQP()
                self.solver.setup(P, gradient, self.A, lower, upper, **OSQP_SETTINGS)
            else:
                self.solver.update(Px=data, q=gradient, l=lower, u=upper)
            solver = self.solver
            result = solve_held(  # OSQP's own SIGINT handler would swallow Ctrl-C
                lambda: solver.solve(raise_error=False),
                lambda r: r.info.status_val == osqp.SolverStatus.OSQP_SIGINT,
            )
        except (ValueError, RuntimeError) as error:
            raise SolverFailure(f"OSQP: {' '.join(str(error).split())}") from None
        status = str(result.info.status)
        if result.x is None or not np.all(np.isfinite(result.x)):
            raise SolverFailure(f"OSQP returned no step ({status})")
        if status not in ("solved", "solved inaccurate", "maximum iterations reached"):
            raise SolverFailure(f"OSQP status {status!r}")
        return np.asarray(result.x, dtype=float)

    def improve(
        self,
        path: FloatArray,
        weights: FloatArray,
        iterations: int,
        deadline: float,
        settle: float = 0.0,
    ) -> FloatArray:
        r"""Up to ``iterations`` accepted-or-rejected Newton steps from a feasible ``path``.

        Args:
            path: Feasible joint path ``(N, nv)``.
            weights: Sample weights ``ω_k``, shape ``(N−1,)``.
            iterations: Iteration budget.
            deadline: ``time.perf_counter()`` value past which it stops.
            settle: Stop as soon as ``max_k m_k ≤ settle`` (0: never), and at most
                :data:`AFTER_CERTIFICATE` iterations after ``max_k m_k ≤ 1`` first held.

        Returns:
            A feasible path whose weighted least squares is no larger than ``path``'s.

        Raises:
            SolverFailure: OSQP failed on a subproblem.
            TimeBudgetExceeded: ``deadline`` passed.
        """
        problem = self.problem
        current = path
        errors, gradients, hessians = problem.linearise(current)
        value = problem.objective(errors, weights)
        left = iterations
        while left > 0:
            left -= 1
            if time.perf_counter() > deadline:
                raise TimeBudgetExceeded
            blocks, data = self._model(hessians, weights)
            gradient = (weights[:, None] * gradients).ravel()
            lower, upper = self._bounds(current)
            delta = self._solve(data, gradient, lower, upper)
            step = delta.reshape(self.blocks, problem.nv)
            predicted = -(
                gradient @ delta + 0.5 * float(np.einsum("bi,bij,bj", step, blocks, step))
            )
            if not predicted > RELATIVE_DECREASE * value + ABSOLUTE_DECREASE:
                break
            trial = current.copy()
            trial[1:] += step
            trial = project_path(trial, problem.lower, problem.upper, problem.step)
            trial_errors = problem.errors(trial)
            trial_value = problem.objective(trial_errors, weights)
            ratio = (value - trial_value) / predicted
            longest = float(np.max(np.abs(step)))
            if ratio > 0.1 and trial_value < value:
                current, value = trial, trial_value
                merit = float(np.max(problem.merits(trial_errors)))
                if merit <= settle:
                    break
                if settle > 0.0 and merit <= 1.0:
                    left = min(left, AFTER_CERTIFICATE)
                if ratio > 0.75 and longest > 0.9 * self.radius:
                    self.radius = min(2.0 * self.radius, 4.0)
                errors, gradients, hessians = problem.linearise(current)
            else:
                self.radius = 0.25 * min(self.radius, longest)
                if self.radius < MIN_RADIUS:
                    break
        return current
