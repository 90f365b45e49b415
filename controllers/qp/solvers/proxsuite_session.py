r"""ProxQP (proxsuite, dense) session: warm started from the previous primal-dual solution."""

from __future__ import annotations

import numpy as np

from .problem import QpProblem
from .session import QpSession, Solution

#: Absolute KKT-residual tolerance: the error on x is about EPS / λ_min(P).
EPS_ABS = 1e-10


class ProxsuiteSession(QpSession):
    """``proxsuite.proxqp.dense.QP`` with box constraints and the rows as ``l ≤ Cx ≤ u``."""

    name = "proxsuite"

    def setup(self, problem: QpProblem) -> None:
        """Allocate the dense QP and load ``problem``."""
        import proxsuite

        n, m = problem.q.shape[0], problem.C.shape[0]
        qp = proxsuite.proxqp.dense.QP(n, 0, m, True)
        qp.settings.eps_abs = EPS_ABS
        qp.settings.eps_rel = 0.0
        qp.settings.verbose = False
        qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
        rows = (problem.C, problem.l, problem.u) if m else (None, None, None)
        qp.init(problem.P, problem.q, None, None, *rows, problem.lb, problem.ub)
        self._qp = qp
        self._solved = proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED
        self._refused: str | None = None  # set up: solvable (ProxQP reports the rest)

    def update(self, problem: QpProblem) -> None:
        """New data in place; the previous solution is the initial guess."""
        if problem.C.shape[0]:
            self._qp.update(
                H=problem.P, g=problem.q, C=problem.C, l=problem.l, u=problem.u,
                l_box=problem.lb, u_box=problem.ub,
            )  # fmt: skip
        else:
            self._qp.update(H=problem.P, g=problem.q, l_box=problem.lb, u_box=problem.ub)

    def solve(self) -> Solution:
        """Solve; found when ProxQP reports ``PROXQP_SOLVED``.

        A failed solve forgets the warm start (the next :meth:`load` sets up afresh): ProxQP
        started from the iterate of an infeasible problem stops at a feasible point it calls
        solved, ~5e-6 from the optimum.
        """
        if self._refused is not None:
            return Solution(None, False, self._refused)
        self._qp.solve()
        status = self._qp.results.info.status
        if status != self._solved:
            self.reset()
            return Solution(None, False, str(status))
        return Solution(np.array(self._qp.results.x), True, str(status))
