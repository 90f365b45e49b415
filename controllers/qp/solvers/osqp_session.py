r"""OSQP (ADMM + polishing) session: warm started from the previous primal-dual solution."""

from __future__ import annotations

from typing import Any

import numpy as np

from otmm_qp.interrupt import solve_held
from otmm_qp.robots.robot import FloatArray

from .problem import QpProblem
from .session import QpSession, Solution, conflicting_bounds

#: OSQP settings giving ~1e-10 accuracy (the error on x is about eps / λ_min(P)).
SETTINGS = {
    "verbose": False, "polishing": True, "eps_abs": 1e-10, "eps_rel": 1e-10, "max_iter": 20000,
}  # fmt: skip
#: OSQP ``status_val`` of "solved" and "solved inaccurate".
_SOLVED = (1, 2)
#: OSQP's status when its own SIGINT handler caught Ctrl-C (``SolverStatus.OSQP_SIGINT``).
_INTERRUPTED = 10
#: Tolerance of the polished second solve after a stop before convergence.
RETRY_EPS = 1e-6
#: Largest bound violation of a polished point that is kept [problem units].
FEASIBILITY_TOL = 1e-9
#: OSQP ``status_val`` of a stop before convergence: iteration limit, time limit, unsolved.
_UNCONVERGED = (7, 8, 11)


class OsqpSession(QpSession):
    r"""``osqp.OSQP`` with constraint matrix :math:`A = [I; C]`, bounds ``[lb; l]``, ``[ub; u]``.

    The sparsity patterns are dense and fixed at :meth:`setup` (upper triangle of ``P``,
    every entry of ``C``), so :meth:`update` only rewrites values.
    """

    name = "osqp"

    def setup(self, problem: QpProblem) -> None:
        """Build the fixed patterns and the solver, then load ``problem``'s values."""
        import osqp
        import scipy.sparse as sparse

        n, m = problem.q.shape[0], problem.C.shape[0]
        rows, cols = np.triu_indices(n)
        order = np.lexsort((rows, cols))  # CSC order: by column, then row
        self._triu = (rows[order], cols[order])
        pattern = sparse.csc_matrix((np.ones(rows.size), self._triu), shape=(n, n))
        # A = [I; C] column by column: the identity entry, then every row of C.
        a_rows = np.concatenate([[j, *range(n, n + m)] for j in range(n)])
        a_cols = np.repeat(np.arange(n), m + 1)
        self._a_values = np.ones((n, m + 1))  # CSC values: column j is [1, C[:, j]]
        a_pattern = sparse.csc_matrix((np.ones(a_rows.size), (a_rows, a_cols)), shape=(n + m, n))
        self._lower, self._upper = np.empty(n + m), np.empty(n + m)
        self._solver = osqp.OSQP()
        self._solver.setup(
            pattern, np.zeros(n), a_pattern, -np.ones(n + m), np.ones(n + m), **SETTINGS
        )
        self.update(problem)

    def _a_data(self, problem: QpProblem) -> FloatArray | None:
        if not problem.C.shape[0]:
            return None  # the identity never changes
        self._a_values[:, 1:] = problem.C.T
        return self._a_values.reshape(-1)

    def update(self, problem: QpProblem) -> None:
        """New values on the fixed patterns (refused, not loaded, if a lower bound > upper).

        OSQP's Python ``update`` drops the C layer's error code: given ``l > u`` it prints an
        error and keeps the previous data, whose solution it then reports ``solved``.
        """
        self._refused = conflicting_bounds(problem)
        if self._refused is not None:
            return
        n = problem.q.shape[0]
        self._lower[:n], self._lower[n:] = problem.lb, problem.l
        self._upper[:n], self._upper[n:] = problem.ub, problem.u
        rows, cols = self._triu
        values = self._a_data(problem)
        extra = {} if values is None else {"Ax": values}
        self._solver.update(
            Px=problem.P[rows, cols], q=problem.q, l=self._lower, u=self._upper, **extra
        )

    def _solve(self) -> Any:
        """One OSQP solve, Ctrl-C kept for Python (:func:`solve_held`)."""
        return solve_held(  # OSQP's own SIGINT handler would swallow Ctrl-C
            lambda: self._solver.solve(raise_error=False),
            lambda result: int(result.info.status_val) == _INTERRUPTED,
        )

    def _polished(self) -> FloatArray | None:
        """A second solve from where OSQP stopped, at :data:`RETRY_EPS`, polished; or None.

        Near-LP problems (``qp_scaled``'s: a 10⁻⁶ Hessian) can exhaust the iterations at 10⁻¹⁰
        while the iterate is close to the optimum; polishing (an equality-constrained solve on
        the active set the iterate shows) then gives the optimum to full accuracy. The polished
        point is kept only when OSQP reports the polish successful and it satisfies every bound
        to :data:`FEASIBILITY_TOL` (checked here, not trusted).
        """
        self._solver.update_settings(eps_abs=RETRY_EPS, eps_rel=RETRY_EPS)
        try:
            result = self._solve()
        finally:
            self._solver.update_settings(eps_abs=SETTINGS["eps_abs"], eps_rel=SETTINGS["eps_rel"])
        if int(getattr(result.info, "status_polish", 0)) != 1 or result.x is None:
            return None
        x = np.array(result.x, dtype=float)
        n = x.size
        rows = (
            np.concatenate([x, self._a_values[:, 1:].T @ x]) if self._a_values.shape[1] > 1 else x
        )
        tol = FEASIBILITY_TOL
        feasible = np.all(rows >= self._lower - tol) and np.all(rows <= self._upper + tol)
        return x if bool(feasible) and rows.size == self._lower.size and n > 0 else None

    def solve(self) -> Solution:
        """Solve; found when OSQP reports solved (or solved inaccurate)."""
        if self._refused is not None:
            return Solution(None, False, self._refused)
        result = self._solve()
        status = int(result.info.status_val)
        if status in _UNCONVERGED:
            polished = self._polished()
            if polished is not None:
                return Solution(polished, True, f"{result.info.status}; polished")
            return Solution(None, False, str(result.info.status), converged=False)
        if status not in _SOLVED:
            return Solution(None, False, str(result.info.status))
        return Solution(np.array(result.x), True, str(result.info.status))
