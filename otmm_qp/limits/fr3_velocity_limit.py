r"""The FR3's position-dependent joint-velocity limits, as the Franka interface computes them.

The Franka Research 3 does not enforce a constant speed box: its joint-velocity limits shrink
near each position limit (the FCI aborts a command outside them). libfranka computes them in
``computeUpperLimitsJointVelocity`` / ``computeLowerLimitsJointVelocity``
(``include/franka/rate_limiting.h``, libfranka 0.15.0; after Franka's "Limits for Franka
Research 3", control_parameters.html), per joint i:

.. math::
    \dot q^{+}_i(\theta) = \min\!\big(v_i,\ \max(0,\ -c_i + \sqrt{\max(0,\ k_i(\theta^{+}_i -
    \theta_i))})\big) - \epsilon,\qquad
    \dot q^{-}_i(\theta) = \max\!\big(-v_i,\ \min(0,\ c_i - \sqrt{\max(0,\ k_i(\theta_i -
    \theta^{-}_i))})\big) + \epsilon

with the constants of :data:`FR3_VELOCITY` (:math:`v` [rad/s], :math:`c` [rad/s], :math:`k`
[rad/s²], :math:`\theta^\pm` [rad]) and :math:`\epsilon = 10^{-3}` rad/s (``kLimitEps``). This
limit is that box (priority 0, like the speed limit: never relaxed), for a 7-joint arm.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from otmm_qp.exceptions import ParameterError
from otmm_qp.limits.limit import Box, Limit
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.validation import Constraints

__all__ = ["FR3_VELOCITY", "Fr3VelocityLimit"]

#: Per joint ``(v, c, k, θ⁺, θ⁻)``: speed cap [rad/s], offset [rad/s], gain [rad/s²], the
#: upper and lower reference positions [rad] (libfranka 0.15.0 ``rate_limiting.h``).
FR3_VELOCITY: tuple[tuple[float, float, float, float, float], ...] = (
    (2.62, 0.30, 12.0, 2.75010, -2.750100),
    (2.62, 0.20, 5.17, 1.79180, -1.791800),
    (2.62, 0.20, 7.00, 2.90650, -2.906500),
    (2.62, 0.30, 8.00, -0.1458, -3.048100),
    (5.26, 0.35, 34.0, 2.81010, -2.810100),
    (4.18, 0.35, 11.0, 4.52050, 0.54092),
    (5.26, 0.35, 34.0, 3.01960, -3.019600),
)
#: libfranka's ``kLimitEps`` [rad/s]: the margin inside each limit.
LIMIT_EPS = 1e-3


class Fr3VelocityLimit(Limit):
    r"""The FR3's joint-velocity box at θ (see the module); a 7-joint arm only.

    Raises:
        ParameterError: At bind, an arm without 7 joints.
    """

    name: ClassVar[str] = "fr3_velocity"
    priority: ClassVar[int] = 0
    parameter_constraints: ClassVar[Constraints] = {}  # libfranka's constants: no parameter

    def bind(self, robot: Robot, dt: float) -> None:
        """Read the constants into ``(7,)`` arrays."""
        super().bind(robot, dt)
        if robot.nv != len(FR3_VELOCITY):
            raise ParameterError(
                "fr3_velocity", f"is the FR3's 7-joint box; the arm has {robot.nv} joints"
            )
        speed, offset, gain, upper, lower = (np.array(c) for c in zip(*FR3_VELOCITY, strict=True))
        self._speed, self._offset, self._gain = speed, offset, gain
        self._upper, self._lower = upper, lower

    def compute_box(self, theta: FloatArray, qdot_prev: FloatArray, out: Box) -> Box:
        """Libfranka's ``(lower, upper)`` joint-velocity limits at ``theta`` [rad/s]."""
        root = np.sqrt(np.maximum(0.0, self._gain * (self._upper - theta)))
        np.minimum(self._speed, np.maximum(0.0, root - self._offset), out=out.upper)
        np.subtract(out.upper, LIMIT_EPS, out=out.upper)
        root = np.sqrt(np.maximum(0.0, self._gain * (theta - self._lower)))
        np.maximum(-self._speed, np.minimum(0.0, self._offset - root), out=out.lower)
        np.add(out.lower, LIMIT_EPS, out=out.lower)
        return out
