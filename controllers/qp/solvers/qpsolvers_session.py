r"""Any qpsolvers backend as a (stateless) session: the plain reference path."""

from __future__ import annotations

import warnings
from typing import Any

import qpsolvers

from otmm_qp.interrupt import sigint_held
from otmm_qp.robots.robot import FloatArray

from .problem import QpProblem
from .session import QpSession, Solution

#: Solver options giving ~1e-10 accuracy; active-set solvers (daqp, quadprog) are exact.
#: (Residual tolerances act on ``Px``, so the error on ``x`` is about ``eps/λ_min(P)``.)
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

        def csc(matrix: Any) -> Any:
            return None if matrix is None else sparse.csc_matrix(matrix)

        problem = qpsolvers.Problem(
            csc(problem.P), problem.q, csc(problem.G), problem.h, csc(problem.A), problem.b,
            problem.lb, problem.ub,
        )  # fmt: skip
    with warnings.catch_warnings():
        # osqp 1.x warns that solve()'s raise_error default will change; qpsolvers calls it.
        warnings.simplefilter("ignore", PendingDeprecationWarning)
        with sigint_held():  # a C solver's own SIGINT handler (OSQP's) would swallow Ctrl-C
            solution = qpsolvers.solve_problem(
                problem, solver=solver, **SOLVER_OPTIONS.get(solver, {})
            )
    return solution.x if solution.found and solution.x is not None else None


class QpsolversSession(QpSession):
    """``qpsolvers.solve_problem`` on a snapshot of the problem: no state, no warm start.

    Args:
        solver: An installed qpsolvers backend, e.g. ``quadprog``, ``clarabel``, ``proxqp``.
    """

    def __init__(self, solver: str) -> None:
        super().__init__()
        self.name = solver
        self._problem: QpProblem | None = None

    def setup(self, problem: QpProblem) -> None:
        """Keep (a copy of) ``problem``."""
        self._problem = problem.copy()

    def update(self, problem: QpProblem) -> None:
        """Keep (a copy of) ``problem``."""
        self._problem = problem.copy()

    def solve(self) -> Solution:
        """Solve the kept problem from scratch."""
        if self._problem is None:
            return Solution(None, False, "no problem loaded")
        x = solve_with_qpsolvers(self._problem.to_qpsolvers(), self.name)
        return Solution(x, x is not None, "found" if x is not None else "no solution")
