"""Resolved motion rate control with the (truncated) Moore–Penrose pseudoinverse."""

from __future__ import annotations

from numbers import Real
from typing import ClassVar

from otmm_qp.backends.backend import (
    RCOND,
    Backend,
    BackendOutput,
    svd_work,
    truncated_pseudoinverse_apply,
)
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.validation import Constraints, Interval, check_params


class PseudoInverseBackend(Backend):
    r"""RMRC: :math:`\dot q = J^{\#}\dot x` (paper eq. 3).

    :math:`J^\# = J^{-1}` for ``nv = n`` and :math:`J^\top(JJ^\top)^{-1}` for ``nv > n``;
    both equal the SVD pseudoinverse :math:`\sum_i \sigma_i^{-1} v_i u_i^\top`.
    Singular values below ``rcond·σ_max`` are truncated, so at an exactly singular ``J``
    only the achievable rows are used (the paper's Fig. 7 case). Near a singularity
    nothing is damped: joint speeds grow as ``1/σ_min``, which is the behaviour under study.

    Status ``saturated`` when ``q̇`` exceeds the robot's joint speed limits (see
    :mod:`otmm_qp.status`).

    Args:
        rcond: Relative truncation threshold, in ``[0, 1)`` (default: the shared
            :data:`~otmm_qp.backends.backend.RCOND`).
    """

    name = "pinv"
    _work: FloatArray | None = None  # svd_work buffers, allocated by bind
    parameter_constraints: ClassVar[Constraints] = {
        "rcond": Interval(Real, 0, 1, closed="left"),
    }

    def __init__(self, rcond: float = RCOND) -> None:
        check_params(self, locals())
        self.rcond = float(rcond)

    def bind(self, robot: Robot, dt: float) -> None:
        """Attach the robot; allocate the step's SVD buffers (:func:`svd_work`)."""
        super().bind(robot, dt)
        self._work = svd_work(robot)

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """``q̇ = J_w^+ ẋ_w`` [rad/s], shape ``(nv,)``."""
        return self.unconstrained_output(
            truncated_pseudoinverse_apply(state, xdot, self.rcond, self._work)
        )
