r"""The persistent solver-session protocol: ``setup`` once, ``update`` each step, ``solve``."""

from __future__ import annotations

import abc
from typing import NamedTuple

from otmm_qp.robots.robot import FloatArray

from .problem import QpProblem


class Solution(NamedTuple):
    """What a session returns.

    Attributes:
        x: The primal solution, shape ``(n,)`` (a fresh array), or None when not found.
        found: Whether the solver reports a solution.
        detail: The solver's own status, e.g. ``exitflag 1`` or ``solved``.
        converged: False when the solver stopped before converging (an iteration or time
            limit): not found, yet not shown infeasible either.
    """

    x: FloatArray | None
    found: bool
    detail: str
    converged: bool = True


def conflicting_bounds(problem: QpProblem) -> str | None:
    """One line naming the first variable or row whose lower bound exceeds its upper bound.

    Returns:
        None when every ``lb_i ≤ ub_i`` and ``l_j ≤ u_j`` (the problem may be feasible).
    """
    for label, lower, upper in (
        ("variable", problem.lb, problem.ub),
        ("row", problem.l, problem.u),
    ):
        clash = (lower > upper).nonzero()[0]
        if clash.size:
            i = int(clash[0])
            return f"infeasible: {label} {i} has lower bound {lower[i]:.6g} > upper {upper[i]:.6g}"
    return None


class QpSession(abc.ABC):
    """One solver instance kept across the steps of a run and warm started.

    :meth:`setup` allocates for a problem's :attr:`~QpProblem.structure` (sizes, equality
    rows); :meth:`update` writes new data of the same structure in place; :meth:`solve`
    solves the current data. :meth:`load` picks between the two.

    Contract: ``P`` is positive definite (the caller's formulation guarantees it); data a
    solver refuses (e.g. a lower bound above an upper one) makes the next :meth:`solve` return
    a :class:`Solution` with ``found=False`` and the reason — never a stale or garbage ``x`` —
    and a later valid :meth:`load` solves normally again.
    """

    #: Registered name.
    name: str = "session"
    #: Why the loaded data cannot be solved (None: it can): set by a solver's set-up and
    #: update, read by its solve.
    _refused: str | None

    def __init__(self) -> None:
        self._structure: tuple[int, int, bytes] | None = None
        self._loaded: QpProblem | None = None
        self._refused = "no problem loaded"

    @abc.abstractmethod
    def setup(self, problem: QpProblem) -> None:
        """Allocate the solver for ``problem``'s structure and load its data (cold start)."""

    @abc.abstractmethod
    def update(self, problem: QpProblem) -> None:
        """Load new data of the structure given to :meth:`setup` (keeps the warm start)."""

    @abc.abstractmethod
    def solve(self) -> Solution:
        """Solve the loaded problem."""

    def load(self, problem: QpProblem) -> None:
        """:meth:`update` if ``problem`` has the last load's structure, else :meth:`setup`."""
        # The same box-only problem object (a backend's reused buffers) cannot change
        # structure: skip recomputing it.
        if not problem.C.shape[0] and problem is self._loaded:
            self.update(problem)
            return
        structure = problem.structure
        if structure == self._structure:
            self.update(problem)
        else:
            self.setup(problem)
            self._structure = structure
        self._loaded = problem

    def reset(self) -> None:
        """Forget the warm start: the next :meth:`load` sets the solver up again."""
        self._structure = None
        self._loaded = None
