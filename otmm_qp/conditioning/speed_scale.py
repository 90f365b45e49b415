r"""Uniform scaling of the joint velocity down to the joint speed limits (direction preserving).

.. math::
    \dot q \leftarrow s\,\dot q,\qquad
    s = \min\Big(1,\ \min_i \frac{m\,\dot q_{max,i}}{|\dot q_i|}\Big)

with the robot's speed limits :math:`\dot q_{max}` [rad/s] and the margin ``m`` ∈ (0, 1]:
the result is parallel to the command and within :math:`m\,\dot q_{max}` on every joint
(what a driver's velocity limiter does instead of clipping each joint, which bends the
direction).
"""

from __future__ import annotations

from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.conditioning.stage import CommandStage
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.validation import Constraints, Interval, check_params

__all__ = ["SpeedScaleStage"]


class SpeedScaleStage(CommandStage):
    """Scale ``q̇`` by one factor so that no joint exceeds ``margin ×`` its speed limit.

    Args:
        margin: Fraction m of the speed limits allowed, in (0, 1].
    """

    name: ClassVar[str] = "speed_scale"
    parameter_constraints: ClassVar[Constraints] = {
        "margin": Interval(Real, 0, 1, closed="right"),
    }

    def __init__(self, margin: float = 1.0) -> None:
        check_params(self, locals())
        self.margin = float(margin)
        self.limit = np.zeros(0)

    def reset(self, robot: Robot, dt: float) -> None:
        """Read the robot's speed limits [rad/s] (inf: none)."""
        super().reset(robot, dt)
        self.limit = self.margin * np.asarray(robot.velocity_limits, dtype=float)

    def apply(self, q: FloatArray, qdot: FloatArray) -> FloatArray:
        """``s q̇`` with the largest s ≤ 1 that keeps every joint within its limit."""
        speed = np.abs(qdot)
        over = speed > self.limit
        if not np.any(over):
            return qdot
        scale = float(np.min(self.limit[over] / speed[over]))
        return qdot * scale

    def label(self) -> str:
        """``speed_scale`` (with the margin when below 1)."""
        return self.name if self.margin == 1.0 else f"{self.name}(margin={self.margin:g})"
