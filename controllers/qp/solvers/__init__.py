r"""QP solver sessions, one file per solver, dispatched by name through :data:`SESSIONS`.

``daqp``, ``proxsuite`` and ``osqp`` are persistent sessions (set up once, updated in place,
warm started); every other installed qpsolvers backend (``quadprog``, ``clarabel``,
``proxqp``, ...) runs through :class:`QpsolversSession` (the stateless reference path). The
names ``direct_daqp``, ``direct_proxsuite``, ``direct_osqp`` of earlier versions are aliases.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Callable

import qpsolvers

from otmm_qp.exceptions import SolverNotFound

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

#: Names of earlier versions, and what they mean now.
ALIASES = {"direct_daqp": "daqp", "direct_osqp": "osqp", "direct_proxsuite": "proxsuite"}


def available_solvers() -> list[str]:
    """Every accepted solver name: sessions, their aliases, and installed qpsolvers backends."""
    names = set(SESSIONS) | set(qpsolvers.available_solvers)
    names |= {alias for alias, target in ALIASES.items() if target in SESSIONS}
    return sorted(names)


def canonical_name(solver: str) -> str:
    """``solver`` with an alias resolved (``direct_daqp`` → ``daqp``)."""
    return ALIASES.get(solver, solver)


def make_session(solver: str) -> QpSession:
    """A new session for ``solver``.

    Raises:
        SolverNotFound: ``solver`` is neither a session nor an installed qpsolvers backend.
    """
    name = canonical_name(solver)
    factory = SESSIONS.get(name)
    if factory is not None:
        return factory()
    if name in qpsolvers.available_solvers:
        return QpsolversSession(name)
    raise SolverNotFound(solver, available_solvers())


__all__ = [
    "ALIASES",
    "BIG",
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
    "canonical_name",
    "make_session",
    "solve_with_qpsolvers",
]
