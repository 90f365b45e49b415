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
least squares decreases: the ratio test, the radius and the stop tests are the one
trust-region driver's (:func:`~otmm_qp.reference.trust_region.minimise`); this module is
its subproblem.
"""

from __future__ import annotations

import numpy as np
import osqp
import scipy.sparse as sp

from otmm_qp.exceptions import SolverFailure
from otmm_qp.interrupt import solve_held
from otmm_qp.reference.problem import BIG, TrackingProblem
from otmm_qp.reference.trust_region import Iterate, Radii, Step, Stopping, minimise
from otmm_qp.robots.robot import FloatArray

#: Floor of the Hessian blocks' eigenvalues (relative to 1 + the largest one).
EIGEN_FLOOR = 1e-9
#: Stop when the model predicts less decrease than this fraction of the objective, plus
#: an absolute floor (objective units: squared tolerances; 1e-12 ≈ errors of 1e-6 tolerance).
RELATIVE_DECREASE = 1e-7
ABSOLUTE_DECREASE = 1e-12
#: Iterations allowed once a path meets every tolerance (it only sharpens the errors).
AFTER_CERTIFICATE = 1
#: Trust radii [rad]: first, largest, smallest.
RADII = Radii(initial=0.3, largest=4.0, smallest=1e-9)
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
    """Persistent OSQP workspace for one task's path optimisation: the least-squares subproblem.

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
        self.radius = RADII.initial
        self.weights = np.ones(self.blocks)
        self._at: FloatArray | None = None  # the path of the model below
        self._model_at: tuple[FloatArray, FloatArray, FloatArray] | None = None

    def _model(self, hessians: FloatArray, weights: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Weighted positive-definite blocks ``ω_k [H_k]_+`` ``(N−1, nv, nv)`` and ``P``'s data."""
        values, vectors = np.linalg.eigh(hessians)  # (B, nv), (B, nv, nv)
        floor = EIGEN_FLOOR * (1.0 + np.max(np.abs(values), axis=1, keepdims=True))
        values = np.maximum(values, floor)
        fixed = np.einsum("bij,bj,bkj->bik", vectors, values, vectors)
        fixed *= weights[:, None, None]
        return fixed, np.asarray(fixed[:, self._rows, self._cols].ravel(), dtype=float)

    def _bounds(self, path: FloatArray, radius: float) -> tuple[FloatArray, FloatArray]:
        """QP bounds ``l ≤ Aδ ≤ u`` at ``path`` with the trust radius ``radius`` [rad]."""
        problem = self.problem
        current = path[1:]
        box_lo = np.maximum(problem.lower - current, -radius)
        box_hi = np.minimum(problem.upper - current, radius)
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

    # ------------------------------------------------------------------ the subproblem
    def start(self, path: FloatArray) -> Iterate:
        """The first iterate; its errors and the model come from one linearisation."""
        errors, _ = self._linearise(path)
        merits = self.problem.merits(errors)
        return Iterate(path, errors, merits, self.problem.objective(errors, self.weights))

    def evaluate(self, path: FloatArray) -> Iterate:
        r"""``φ`` = the weighted least squares; merits ``m_k`` of every sample ``(N,)``."""
        errors = self.problem.errors(path)
        merits = self.problem.merits(errors)
        return Iterate(path, errors, merits, self.problem.objective(errors, self.weights))

    def _linearise(
        self, path: FloatArray
    ) -> tuple[FloatArray, tuple[FloatArray, FloatArray, FloatArray]]:
        """Errors ``(N, n)`` and the model at ``path`` (kept while the iterate stays there).

        The model: the weighted blocks ``(N−1, nv, nv)``, ``P``'s data and the weighted
        gradient ``((N−1)·nv,)``.
        """
        errors, gradients, hessians = self.problem.linearise(path)
        blocks, data = self._model(hessians, self.weights)
        gradient = (self.weights[:, None] * gradients).ravel()
        self._at, self._model_at = path, (blocks, data, gradient)
        return errors, self._model_at

    def step(self, iterate: Iterate, radius: float) -> Step:
        r"""The QP step of the module docstring; ``pred = −(gᵀδ + ½ δᵀ P δ)``.

        Raises:
            SolverFailure: OSQP failed.
        """
        model = self._model_at
        if self._at is not iterate.path or model is None:
            _, model = self._linearise(iterate.path)
        blocks, data, gradient = model
        lower, upper = self._bounds(iterate.path, radius)
        delta = self._solve(data, gradient, lower, upper)
        step = delta.reshape(self.blocks, self.problem.nv)
        predicted = -(gradient @ delta + 0.5 * float(np.einsum("bi,bij,bj", step, blocks, step)))
        return Step(step, float(predicted))

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
        self.weights = weights
        self._at = self._model_at = None
        stopping = Stopping(
            relative_decrease=RELATIVE_DECREASE,
            absolute_decrease=ABSOLUTE_DECREASE,
            settle=settle,
            after_certificate=AFTER_CERTIFICATE if settle > 0.0 else None,
            raise_at_deadline=True,
        )
        outcome = minimise(self, path, iterations, deadline, RADII, stopping, self.radius)
        self.radius = outcome.radius
        return path if outcome.current is None else outcome.current
