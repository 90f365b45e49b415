r"""The QP data handed to a solver session: one form every solver reads directly."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import qpsolvers
from numpy.typing import NDArray

from otmm_qp.exceptions import DimensionError
from otmm_qp.robots.robot import FloatArray

#: Infinite bounds are passed to the solvers as ±BIG (some reject inf).
BIG = 1e9


class QpProblem(NamedTuple):
    r"""A dense convex QP with a box and two-sided general rows.

    .. math::
        \min_x\ \tfrac12 x^\top P x + q^\top x
        \quad\text{s.t.}\quad lb \le x \le ub,\quad l \le C x \le u

    A row with ``l_i = u_i`` is an equality. Unbounded sides hold ``±BIG``.

    Attributes:
        P: Hessian, symmetric positive definite, shape ``(n, n)``.
        q: Linear cost, shape ``(n,)``.
        lb: Lower variable bounds, shape ``(n,)``.
        ub: Upper variable bounds, shape ``(n,)``.
        C: General constraint rows, shape ``(m, n)`` (``m = 0``: box only).
        l: Lower row bounds, shape ``(m,)``.
        u: Upper row bounds, shape ``(m,)``.
    """

    P: FloatArray
    q: FloatArray
    lb: FloatArray
    ub: FloatArray
    C: FloatArray
    l: FloatArray  # noqa: E741 - the standard name of the row lower bound
    u: FloatArray

    @classmethod
    def allocate(cls, n: int, m: int = 0, box: FloatArray | None = None) -> QpProblem:
        """Uninitialised arrays for ``n`` variables and ``m`` general rows.

        Args:
            n: Number of variables.
            m: Number of general rows.
            box: An array of shape ``(2, n)`` whose rows become ``lb`` and ``ub`` (views: a
                caller that writes its box there hands it to the solver without a copy);
                fresh arrays when None.

        Raises:
            DimensionError: ``box`` is not of shape ``(2, n)``.
        """
        if box is None:
            box = np.empty((2, n))
        elif box.shape != (2, n):
            raise DimensionError("box", (2, n), box.shape)
        return cls(
            np.empty((n, n)), np.empty(n), box[0], box[1],
            np.zeros((m, n)), np.full(m, -BIG), np.full(m, BIG),
        )  # fmt: skip

    @property
    def structure(self) -> tuple[int, int, bytes]:
        """``(n, m, equality flags as bytes)``: what a solver session allocates for."""
        m = self.C.shape[0]
        return self.q.shape[0], m, (self.l == self.u).tobytes() if m else b""

    def with_rows(self, rows: NDArray[np.bool_]) -> QpProblem:
        """The same QP keeping only the general rows in ``rows`` (shape ``(m,)``, bool).

        ``P``, ``q`` and the box are shared (not copied); the kept rows are copies. Its
        optimum is a relaxation's: the whole QP's optimum when it meets the dropped rows.
        """
        return QpProblem(self.P, self.q, self.lb, self.ub, self.C[rows], self.l[rows], self.u[rows])

    def copy(self) -> QpProblem:
        """A deep copy (a snapshot of buffers that the next step overwrites)."""
        return QpProblem(*(np.array(a, dtype=float) for a in self))

    def to_qpsolvers(self) -> qpsolvers.Problem:
        """The same QP as a :class:`qpsolvers.Problem` (``Gx ≤ h``, ``Ax = b``)."""
        equality = self.l == self.u
        upper = ~equality & (self.u < BIG)
        lower = ~equality & (self.l > -BIG)
        G = np.vstack([self.C[upper], -self.C[lower]])
        h = np.concatenate([self.u[upper], -self.l[lower]])
        return qpsolvers.Problem(
            self.P.copy(), self.q.copy(),
            G if G.shape[0] else None, h if h.shape[0] else None,
            self.C[equality] if equality.any() else None,
            self.l[equality] if equality.any() else None,
            self.lb.copy(), self.ub.copy(),
        )  # fmt: skip
