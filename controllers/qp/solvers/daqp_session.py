r"""DAQP (dual active-set) session: warm started from the previous active set."""

from __future__ import annotations

from ctypes import c_int
from typing import Any

import numpy as np

from .problem import QpProblem
from .session import QpSession, Solution

#: DAQP sense flags of an equality row: ACTIVE (1) + IMMUTABLE (4).
_EQUALITY = 5
#: The details of DAQP's success flags (1: optimal, 2: soft optimal), built once.
_DETAILS = {flag: f"exitflag {flag}" for flag in (1, 2)}


class DaqpSession(QpSession):
    """``daqp.Model``: box rows first, then the general rows (DAQP's own layout)."""

    name = "daqp"
    _model: Any = None  # the daqp.Model; None before set-up or after a refused one

    def setup(self, problem: QpProblem) -> None:
        """Allocate a ``daqp.Model`` and the stacked row bounds."""
        import daqp

        n, m = problem.q.shape[0], problem.C.shape[0]
        self._upper = np.empty(n + m)
        self._lower = np.empty(n + m)
        sense = np.zeros(n + m, dtype=c_int)
        sense[n:][problem.l == problem.u] = _EQUALITY
        self._stack(problem)
        model = daqp.Model()
        flag, _ = model.setup(problem.P, problem.q, problem.C, self._upper, self._lower, sense)
        # DAQP refuses data it cannot use (lb > ub, P not positive definite) with a negative
        # flag; its solve() would then return a stale or NaN x flagged optimal, or raise.
        self._model = model if flag >= 0 else None
        self._refused = None if flag >= 0 else f"set-up exitflag {flag}"

    def _stack(self, problem: QpProblem) -> None:
        n = problem.q.shape[0]
        self._upper[:n], self._upper[n:] = problem.ub, problem.u
        self._lower[:n], self._lower[n:] = problem.lb, problem.l

    def load(self, problem: QpProblem) -> None:
        """:meth:`QpSession.load`; the same box-only problem again goes straight to DAQP."""
        model = self._model
        if problem is self._loaded and model is not None and not problem.C.shape[0]:
            # No structure to compare (see QpSession.load); the call of _update_box inlined.
            flag = model.update(problem.P, problem.q, None, problem.ub, problem.lb)
            self._refused = None if flag >= 0 else f"update exitflag {flag}"
        else:
            super().load(problem)

    def _update_box(self, problem: QpProblem) -> None:
        # Positional (H, f, A, bupper, blower): keyword parsing costs more in Cython.
        flag = self._model.update(problem.P, problem.q, None, problem.ub, problem.lb)
        self._refused = None if flag >= 0 else f"update exitflag {flag}"

    def update(self, problem: QpProblem) -> None:
        """New ``P``, ``q``, bounds (and rows); the active set of the last solve is kept."""
        if self._model is None:  # the last set-up was refused: set up again
            self.setup(problem)
            return
        if not problem.C.shape[0]:  # box only: the bounds are the problem's own arrays
            self._update_box(problem)
            return
        self._stack(problem)
        flag = self._model.update(
            H=problem.P, f=problem.q, A=problem.C, bupper=self._upper, blower=self._lower
        )
        self._refused = None if flag >= 0 else f"update exitflag {flag}"

    def solve(self) -> Solution:
        """Solve; found when DAQP's exit flag is positive (and it took the data)."""
        if self._refused is not None:
            return Solution(None, False, self._refused)
        x, _, exitflag, _ = self._model.solve()
        detail = _DETAILS.get(exitflag) or f"exitflag {exitflag}"
        if exitflag <= 0:
            return Solution(None, False, detail)
        # DAQP returns a new float64 array per solve: no copy or conversion needed. (All
        # fields through tuple.__new__: a third cheaper than Solution(...), on every QP step.)
        return tuple.__new__(Solution, (x, True, detail, True))
