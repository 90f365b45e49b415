"""The backend interface: turn a (filtered) task velocity into joint velocities."""

from __future__ import annotations

import abc
from typing import Final, NamedTuple

import numpy as np

from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.status import Status, exceeds_speed_limits, speed_limit_thresholds

# Aliases of the Status members, kept importable for code written before the enum.
STATUS_OK: Final = Status.OK
STATUS_BOUNDED: Final = Status.BOUNDED
STATUS_INFEASIBLE: Final = Status.INFEASIBLE
STATUS_STUCK: Final = Status.STUCK
STATUS_NONFINITE: Final = Status.NONFINITE
STATUS_RELAXED: Final = Status.RELAXED
STATUS_SATURATED: Final = Status.SATURATED
#: The statuses counted by the metrics (``status_<name>`` columns) before the enum existed;
#: :class:`~otmm_qp.status.Status` lists them all.
STATUSES: Final = (STATUS_OK, STATUS_BOUNDED, STATUS_INFEASIBLE, STATUS_STUCK, STATUS_NONFINITE)

#: Singular values below ``RCOND·σ_max`` count as zero: the one rank cutoff of every backend.
RCOND: Final = 1e-10
_TINY: Final = float(np.finfo(float).tiny)


def rank_cutoff(sigma: FloatArray, rcond: float = RCOND) -> float:
    r"""Threshold below which a singular value is dropped: :math:`\max(r\,\sigma_{max}, tiny)`.

    Args:
        sigma: Singular values, descending, shape ``(k,)``.
        rcond: Relative threshold ``r`` in ``[0, 1)``.
    """
    return max(rcond * float(sigma[0]), _TINY) if sigma.size else _TINY


class BackendOutput(NamedTuple):
    r"""Result of one backend solve.

    Attributes:
        qdot: Joint velocity [rad/s], shape ``(nv,)``.
        status: A :class:`~otmm_qp.status.Status`.
        damping: Damping factor λ [task units] of the step — the λ of
            :math:`J^\top(JJ^\top + \lambda^2 I)^{-1}`, i.e. the QP weight of
            :math:`\|\dot q\|^2` is λ² — NaN when the backend has none.
        scale: Fraction α ∈ [0, 1] of the command realised (1 unless direction-preserving).
    """

    qdot: FloatArray
    status: str = Status.OK
    damping: float = float("nan")
    scale: float = 1.0


class Backend(abc.ABC):
    r"""Resolve ``J_w q̇ ≈ ẋ_w`` for ``q̇``, shape ``(nv,)``.

    The backend receives the step's :class:`~otmm_qp.state.KinematicState` — use its
    ``task_jacobian`` and SVD (``U``, ``sigma``, ``Vt``), never recompute them — and the
    *weighted* command ``ẋ_w``, shape ``(n,)``. :meth:`bind` is called once per run
    before the first step, with the robot (for its limits) and the time step ``dt`` [s];
    allocate persistent solvers there.
    """

    #: Registered name (informative).
    name: str = "backend"
    robot: Robot
    dt: float

    def bind(self, robot: Robot, dt: float) -> None:
        """Attach the robot and the control period ``dt`` [s]; called once per run."""
        self.robot = robot
        self.dt = dt
        limits = np.asarray(robot.velocity_limits, dtype=float)
        self._speed_limits: FloatArray | None = (
            speed_limit_thresholds(limits) if np.isfinite(limits).any() else None
        )

    def reset(self) -> None:  # noqa: B027 - optional hook
        """Forget warm starts and per-run state (called at the start of each run)."""

    @abc.abstractmethod
    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Joint velocity for the weighted task velocity ``xdot`` (n,).

        Args:
            state: Kinematic state of this step (shared SVD).
            xdot: Weighted task velocity ``ẋ_w``, shape ``(n,)``.
            qdot_prev: Joint velocity of the previous step [rad/s], shape ``(nv,)``.
        """

    def unconstrained_output(self, qdot: FloatArray, damping: float = np.nan) -> BackendOutput:
        """``ok``, or ``saturated`` when ``qdot`` exceeds the bound robot's speed limits.

        For backends that do not enforce joint limits (see :mod:`otmm_qp.status`).
        """
        limits = getattr(self, "_speed_limits", None)  # None: unbound, or no finite limit
        if limits is not None and exceeds_speed_limits(qdot, limits):
            return BackendOutput(qdot, Status.SATURATED, damping)
        return BackendOutput(qdot, Status.OK, damping)


def truncated_pseudoinverse_apply(
    state: KinematicState, xdot: FloatArray, rcond: float = RCOND
) -> FloatArray:
    r"""``J_w^+ ẋ`` from the shared SVD, dropping singular values below :func:`rank_cutoff`.

    .. math:: \dot q = \sum_{i:\,\sigma_i > \epsilon} \frac{u_i^\top \dot x}{\sigma_i} v_i

    An exactly singular ``J`` thus uses only its achievable rows (the paper's case).
    """
    sigma = state.sigma
    if not sigma.size:
        return np.zeros(state.Vt.shape[1])
    cutoff = rank_cutoff(sigma, rcond)
    if sigma[-1] > cutoff:  # full rank: no masking needed (the common case)
        result: FloatArray = state.Vt.T @ ((xdot @ state.U) / sigma)
        return result
    keep = sigma > cutoff
    coefficients = (xdot @ state.U[:, keep]) / sigma[keep]
    return np.asarray(state.Vt[keep].T @ coefficients, dtype=float)
