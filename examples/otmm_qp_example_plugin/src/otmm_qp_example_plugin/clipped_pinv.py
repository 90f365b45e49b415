"""A speed-clipped pseudoinverse: RMRC whose joint speed is scaled into a bound."""

from __future__ import annotations

from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.backends.backend import Backend, BackendOutput, truncated_pseudoinverse_apply
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.status import Status
from otmm_qp.validation import Constraints, Interval, check_params


class ClippedPseudoInverseBackend(Backend):
    r"""Pseudoinverse followed by a uniform, direction-preserving speed clip.

    .. math::
        \dot q_0 = J_w^{+}\dot x_w,\qquad
        \alpha = \min\Big(1,\ \min_i \frac{\bar v_i}{|\dot q_{0,i}|}\Big),\qquad
        \dot q = \alpha\,\dot q_0

    with :math:`\bar v_i = \min(\text{max\_speed},\ \text{velocity limit}_i)` [rad/s]. The
    joint motion keeps its direction, so the task moves along the commanded direction at a
    fraction ``α`` of the commanded speed (reported as ``scale``).

    Args:
        max_speed: Joint speed bound > 0 [rad/s].
        rcond: Relative truncation threshold of the pseudoinverse, in ``[0, 1)``.

    Raises:
        ParameterError: A parameter is out of range.
    """

    name = "example_clipped_pinv"
    #: What each parameter accepts: checked once by ``check_params``, listed by
    #: ``otmm-qp list --params``.
    parameter_constraints: ClassVar[Constraints] = {
        "max_speed": Interval(Real, 0, None, closed="neither", unit="rad/s"),
        "rcond": Interval(Real, 0, 1, closed="left"),
    }

    def __init__(self, max_speed: float = 2.0, rcond: float = 1e-10) -> None:
        check_params(self, locals())  # first: a bad value is refused before anything else
        self.max_speed = float(max_speed)
        self.rcond = float(rcond)

    def bind(self, robot: Robot, dt: float) -> None:
        """Combine ``max_speed`` with the robot's own speed limits [rad/s]."""
        super().bind(robot, dt)
        self._bound = np.minimum(self.max_speed, robot.velocity_limits)  # (nv,) [rad/s]

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Clipped pseudoinverse joint velocity [rad/s], shape ``(nv,)``."""
        qdot = truncated_pseudoinverse_apply(state, xdot, self.rcond)
        speed = np.abs(qdot)
        over = speed > self._bound
        if not np.any(over):
            return BackendOutput(qdot, Status.OK)
        alpha = float(np.min(self._bound[over] / speed[over]))
        return BackendOutput(alpha * qdot, Status.BOUNDED, scale=alpha)
