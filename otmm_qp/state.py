"""Per-step kinematic state: J and its SVD computed once, shared by filters and backend."""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from scipy.linalg import lapack

from otmm_qp.exceptions import DimensionError, NonFiniteState, ParameterError
from otmm_qp.robots.robot import FloatArray, Robot

_unit_weights: dict[int, FloatArray] = {}
_dgesdd = lapack.dgesdd


class SvdWorkspace:
    r"""What LAPACK ``dgesdd`` needs for one Jacobian shape ``(n, m)``, set up once per thread.

    Attributes:
        scratch: Fortran-ordered ``(n, m)`` array the matrix is copied into and that
            ``dgesdd`` overwrites (``overwrite_a``): the step's one copy of the matrix.
        lwork: The workspace length, computed once:
            :math:`4k^2 + \max(n, m) + 9k`, ``k = min(n, m)`` (LAPACK's requirement for the
            thin SVD with vectors, the length scipy's wrapper uses by default). scipy's wrapper
            allocates ``work`` on every call whatever its length, and the blocked code paths a
            larger ("optimal", ``dgesdd_lwork``: 434 for 6 × 7) workspace enables start at
            sizes far above an arm's Jacobian, so the smallest valid length is the cheapest
            and keeps LAPACK on the path (and the rounding) of every earlier release.
    """

    __slots__ = ("lwork", "scratch")

    def __init__(self, shape: tuple[int, int]) -> None:
        rows, columns = shape
        self.scratch: FloatArray = np.empty(shape, order="F")
        k = min(rows, columns)
        self.lwork = max(4 * k * k + max(rows, columns) + 9 * k, 1)


class _Workspaces(threading.local):
    """Per thread (a worker may run steps in threads), one workspace per matrix shape."""

    def __init__(self) -> None:
        self.by_shape: dict[tuple[int, int], SvdWorkspace] = {}


_workspaces = _Workspaces()


def svd_workspace(shape: tuple[int, int]) -> SvdWorkspace:
    """This thread's :class:`SvdWorkspace` for matrices of ``shape`` (created on first use)."""
    cache = _workspaces.by_shape
    workspace = cache.get(shape)
    if workspace is None:
        workspace = cache[shape] = SvdWorkspace(shape)
    return workspace


def thin_svd(matrix: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Thin SVD ``(U (n, k), σ (k,), Vᵀ (k, m))`` of a finite matrix, ``k = min(n, m)``.

    Calls LAPACK ``dgesdd`` directly (about half the overhead of ``numpy.linalg.svd`` on the
    small matrices of arm Jacobians) on a copy of ``matrix`` in this thread's Fortran-ordered
    :class:`SvdWorkspace` (``overwrite_a``, ``lwork`` computed once per shape), and falls back
    to ``dgesvd`` if it does not converge. ``U``, ``σ`` and ``Vᵀ`` are new arrays (the
    caller keeps them); ``matrix`` is not modified.
    """
    if matrix.ndim != 2 or not matrix.size:  # nothing to reuse: LAPACK's own checks and copy
        U, sigma, Vt, info = lapack.dgesdd(matrix, compute_uv=1, full_matrices=0)
    else:
        workspace = _workspaces.by_shape.get(matrix.shape) or svd_workspace(matrix.shape)
        scratch = workspace.scratch
        scratch[...] = matrix  # setitem: the copy without np.copyto's dispatch
        U, sigma, Vt, info = _dgesdd(scratch, 1, 0, workspace.lwork, 1)
    if info != 0:
        U, sigma, Vt, info = lapack.dgesvd(matrix, compute_uv=1, full_matrices=0)
        if info != 0:  # only NaN/inf input gets here: report it through σ
            sigma = np.full(min(matrix.shape), np.nan)
    return U, sigma, Vt


class KinematicState(NamedTuple):
    r"""Everything a control step needs about the arm at ``q`` (immutable).

    The task may be weighted by a diagonal :math:`W` (to make metres and radians
    comparable in a pose task). Filters and backends work in the weighted task space:

    .. math:: J_w = W J = U \Sigma V^\top, \qquad \dot x_w = W \dot x

    Attributes:
        q: Configuration, shape ``(nq,)``.
        x: Task value at ``q`` (see :class:`~otmm_qp.robots.Robot`).
        jacobian: Physical Jacobian ``J``, shape ``(n, nv)``.
        weight: Diagonal of ``W``, shape ``(n,)``.
        task_jacobian: ``J_w = W J``, shape ``(n, nv)``.
        U: Left singular vectors of ``J_w``, shape ``(n, k)``, ``k = min(n, nv)``.
        sigma: Singular values of ``J_w``, descending, shape ``(k,)``.
        Vt: Right singular vectors (rows), shape ``(k, nv)``.

    A named tuple rather than a frozen dataclass: as immutable, and built in a third of the
    time (a frozen dataclass sets each field through ``object.__setattr__``; this is built on
    every control step).
    """

    q: FloatArray
    x: FloatArray
    jacobian: FloatArray
    weight: FloatArray
    task_jacobian: FloatArray
    U: FloatArray
    sigma: FloatArray
    Vt: FloatArray

    @classmethod
    def compute(
        cls, robot: Robot, q: FloatArray, weight: FloatArray | Sequence[float] | None = None
    ) -> KinematicState:
        """Evaluate kinematics and the one SVD of this step.

        Args:
            robot: The arm.
            q: Configuration, shape ``(nq,)``.
            weight: Task weight diagonal, shape ``(n,)`` (an array, or a sequence read as
                one); identity when None. (Its values are
                checked once per run by :func:`~otmm_qp.simulation.simulate.simulate`.)

        Raises:
            DimensionError: ``q`` is not of shape ``(nq,)`` or ``weight`` not ``(n,)``.
            ParameterError: ``weight`` is not numbers.
            NonFiniteState: The Jacobian contains NaN or inf.
        """
        q = np.asarray(q, dtype=float)  # no copy for a float array (the common case)
        if q.shape != (robot.nq,):
            raise DimensionError("q", (robot.nq,), q.shape)
        x, jacobian = robot.kinematics(q)
        if weight is None:
            n = jacobian.shape[0]
            weight = _unit_weights.get(n)
            if weight is None:
                weight = _unit_weights.setdefault(n, np.ones(n))
                weight.flags.writeable = False
            task_jacobian = jacobian
        else:
            if not isinstance(weight, np.ndarray):
                weight = _as_weight(weight, jacobian.shape[0])
            if weight.shape != (jacobian.shape[0],):
                raise DimensionError("weight", (jacobian.shape[0],), weight.shape)
            task_jacobian = weight[:, None] * jacobian
        U, sigma, Vt = thin_svd(task_jacobian)
        # NaN/inf anywhere in J shows in σ_max (LAPACK propagates it): one scalar check.
        if sigma.size and not math.isfinite(sigma[0]):
            raise NonFiniteState("jacobian", "contains NaN or inf; the configuration diverged")
        return cls(q, x, jacobian, weight, task_jacobian, U, sigma, Vt)

    @property
    def task_dim(self) -> int:
        """Task dimension ``n``."""
        return int(self.jacobian.shape[0])

    @property
    def sigma_min(self) -> float:
        """Smallest singular value of the task Jacobian, counting missing ranks as zero.

        For ``nv < n`` the Jacobian has at most ``nv`` nonzero singular values, so σ_min = 0.
        """
        if self.sigma.size < self.task_dim:
            return 0.0
        return float(self.sigma[-1])

    @property
    def weakest_joint_direction(self) -> FloatArray:
        """Right singular vector of σ_min, shape ``(nv,)``: joint motion the task barely sees."""
        return self.Vt[-1]


def _as_weight(weight: object, n: int) -> FloatArray:
    """A task weight given as a sequence, as a float array (the slow path: not an ndarray).

    Raises:
        ParameterError: It is not a sequence of numbers (names what it got).
    """
    try:
        return np.asarray(weight, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(
            "weight", f"must be {n} numbers (task weight), got {type(weight).__name__}"
        ) from None
