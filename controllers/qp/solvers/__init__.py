r"""QP solver sessions, one file per solver, dispatched by name through :data:`SESSIONS`.

``daqp``, ``proxsuite`` and ``osqp`` are persistent sessions (set up once, updated in place,
warm started); every other installed qpsolvers backend (``quadprog``, ``clarabel``,
``proxqp``, ...) runs through :class:`QpsolversSession` (the stateless reference path).
A solver name is a session name or an installed qpsolvers backend, nothing else.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Callable, Sequence

import qpsolvers

from otmm_qp.exceptions import OtmmError, ParameterError, SolverNotFound

from .daqp_session import DaqpSession
from .osqp_session import OsqpSession
from .problem import BIG, QpProblem
from .proxsuite_session import ProxsuiteSession
from .qpsolvers_session import (
    SOLVER_OPTIONS,
    QpsolversSession,
    solve_with_qpsolvers,
)
from .session import QpSession, Solution

#: Persistent sessions by name, registered when their package is importable.
SESSIONS: dict[str, Callable[[], QpSession]] = {}
for _name, _module, _session in (
    ("daqp", "daqp", DaqpSession),
    ("osqp", "osqp", OsqpSession),
    ("proxsuite", "proxsuite", ProxsuiteSession),
):
    if importlib.util.find_spec(_module) is not None:
        SESSIONS[_name] = _session

#: Solver names that were renamed, for the one-line refusal only (never resolved).
RENAMED = {"direct_daqp": "daqp", "direct_osqp": "osqp", "direct_proxsuite": "proxsuite"}


def available_solvers() -> list[str]:
    """Every accepted solver name: the sessions and the installed qpsolvers backends."""
    return sorted(set(SESSIONS) | set(qpsolvers.available_solvers))


def unknown_solver(solver: str, installed: Sequence[str]) -> OtmmError:
    """The error for a solver name not in ``installed``.

    Returns:
        ``ParameterError`` naming the new name of a renamed one (``solver: 'direct_daqp' is now
        called 'daqp' (the persistent daqp session); write solver: daqp``), else
        ``SolverNotFound`` (``unknown QP solver 'x'; installed: ...``).
    """
    new = RENAMED.get(solver)
    if new is not None:
        return ParameterError(
            "solver",
            f"{solver!r} is now called {new!r} (the persistent {new} session); write solver: {new}",
        )
    return SolverNotFound(solver, installed)


def make_session(solver: str) -> QpSession:
    """A new session for ``solver``.

    Raises:
        SolverNotFound: ``solver`` is neither a session nor an installed qpsolvers backend.
    """
    factory = SESSIONS.get(solver)
    if factory is not None:
        return factory()
    if solver in qpsolvers.available_solvers:
        return QpsolversSession(solver)
    raise unknown_solver(solver, available_solvers())


__all__ = [
    "BIG",
    "RENAMED",
    "SESSIONS",
    "SOLVER_OPTIONS",
    "DaqpSession",
    "OsqpSession",
    "ProxsuiteSession",
    "QpProblem",
    "QpSession",
    "QpsolversSession",
    "Solution",
    "available_solvers",
    "make_session",
    "solve_with_qpsolvers",
    "unknown_solver",
]
