r"""The joint-acceleration limit around the previous velocity: ``|q̇ − q̇_prev| ≤ a_max·dt``."""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from otmm_qp.limits.limit import Box, Limit, per_joint
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.validation import Constraints, check_params, positive_per_joint

__all__ = ["AccelerationLimit"]


class AccelerationLimit(Limit):
    r"""The joint velocity may change by at most ``a_max·dt`` per step.

    .. math:: \dot q_{prev} - a_{max}\,dt \le \dot q \le \dot q_{prev} + a_{max}\,dt

    Priority 2: the first limit a non-raising policy gives up (a joint beyond its position
    limit then returns at the speed limit rather than at ``a_max``).

    Args:
        a_max: ``a_max`` [rad/s²], > 0 (inf: that joint unlimited), a scalar or one per joint.

    Raises:
        ParameterError: Some ``a_max`` is not > 0 (or NaN).
    """

    name: ClassVar[str] = "acceleration"
    priority: ClassVar[int] = 2
    parameter_constraints: ClassVar[Constraints] = {
        "a_max": positive_per_joint("rad/s²"),
    }

    def __init__(self, a_max: float | Sequence[float]) -> None:
        check_params(self, locals())
        self.a_max = a_max

    def bind(self, robot: Robot, dt: float) -> None:
        """``a_max·dt`` [rad/s], shape ``(nv,)``.

        Raises:
            DimensionError: ``a_max`` is neither a scalar nor of shape ``(nv,)``.
        """
        super().bind(robot, dt)
        acceleration = np.asarray(per_joint(self.a_max, "a_max", robot.nv), dtype=float)
        self.step: FloatArray = acceleration * dt

    def compute_box(self, theta: FloatArray, qdot_prev: FloatArray, out: Box) -> Box:
        """``(q̇_prev − a_max·dt, q̇_prev + a_max·dt)`` [rad/s] into ``out``."""
        np.subtract(qdot_prev, self.step, out=out.lower)
        np.add(qdot_prev, self.step, out=out.upper)
        return out
