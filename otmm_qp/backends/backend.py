"""The backend interface: turn a (filtered) task velocity into joint velocities."""

from __future__ import annotations

import abc
from typing import Final, NamedTuple

import numpy as np

from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState

#: Step solved with no bound active.
STATUS_OK: Final = "ok"
#: Step solved with at least one joint bound active.
STATUS_BOUNDED: Final = "bounded"
#: No feasible joint velocity; the infeasibility policy decided what was returned.
STATUS_INFEASIBLE: Final = "infeasible"
#: Direction-preserving solve could only scale the command below its threshold.
STATUS_STUCK: Final = "stuck"
#: The backend returned non-finite values; the step was replaced by zero joint speed.
STATUS_NONFINITE: Final = "nonfinite"
_TINY: Final = float(np.finfo(float).tiny)
STATUSES: Final = (STATUS_OK, STATUS_BOUNDED, STATUS_INFEASIBLE, STATUS_STUCK, STATUS_NONFINITE)


class BackendOutput(NamedTuple):
    """Result of one backend solve.

    Attributes:
        qdot: Joint velocity [rad/s], shape ``(nv,)``.
        status: One of :data:`STATUSES`.
        damping: Damping λ used [task units], NaN when the backend has none.
        scale: Fraction α ∈ [0, 1] of the command realised (1 unless direction-preserving).
    """

    qdot: FloatArray
    status: str = STATUS_OK
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


def truncated_pseudoinverse_apply(
    state: KinematicState, xdot: FloatArray, rcond: float = 1e-10
) -> FloatArray:
    r"""``J_w^+ ẋ`` from the shared SVD, dropping singular values below ``rcond·σ_max``.

    .. math:: \dot q = \sum_{i:\,\sigma_i > \epsilon} \frac{u_i^\top \dot x}{\sigma_i} v_i

    An exactly singular ``J`` thus uses only its achievable rows (the paper's case).
    """
    sigma = state.sigma
    if not sigma.size:
        return np.zeros(state.Vt.shape[1])
    cutoff = max(rcond * float(sigma[0]), _TINY)
    if sigma[-1] > cutoff:  # full rank: no masking needed (the common case)
        result: FloatArray = state.Vt.T @ ((xdot @ state.U) / sigma)
        return result
    keep = sigma > cutoff
    coefficients = (xdot @ state.U[:, keep]) / sigma[keep]
    return np.asarray(state.Vt[keep].T @ coefficients, dtype=float)
