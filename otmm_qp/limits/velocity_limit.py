r"""The joint-speed limit: ``−q̇_max ≤ q̇ ≤ q̇_max`` [rad/s]."""

from __future__ import annotations

from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.limits.limit import Box, Limit
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.validation import Constraints, Interval, check_params

__all__ = ["VelocityLimit"]


class VelocityLimit(Limit):
    r"""The robot's joint-speed limits, optionally capped by a uniform ``max_speed``.

    .. math:: -\dot q_{max} \le \dot q \le \dot q_{max},\qquad
              \dot q_{max,i} = \min(\dot q_{max,i}^{robot},\ \text{max\_speed})

    Priority 0: never relaxed (the drives cannot exceed it). The box depends on neither θ nor
    ``q̇_prev``, so it is computed once, at :meth:`bind`.

    Args:
        max_speed: Extra uniform cap [rad/s], finite and > 0 (e.g. for planar arms, whose
            speed is unlimited); None: the robot's limits only (inf where it has none).

    Raises:
        ParameterError: ``max_speed`` is not a finite number > 0.
    """

    name: ClassVar[str] = "velocity"
    priority: ClassVar[int] = 0
    static: ClassVar[bool] = True
    parameter_constraints: ClassVar[Constraints] = {
        "max_speed": [Interval(Real, 0, None, closed="neither", unit="rad/s"), None],
    }

    def __init__(self, max_speed: float | None = None) -> None:
        check_params(self, locals())
        self.max_speed = None if max_speed is None else float(max_speed)

    def bind(self, robot: Robot, dt: float) -> None:
        """Read the robot's speed limits [rad/s], shape ``(nv,)``, and apply the cap."""
        super().bind(robot, dt)
        speed = np.array(robot.velocity_limits, dtype=float)
        if self.max_speed is not None:
            speed = np.minimum(speed, self.max_speed)
        self.speed: FloatArray = speed
        self._negative: FloatArray = -speed

    def compute_box(self, theta: FloatArray, qdot_prev: FloatArray, out: Box) -> Box:
        """``(−q̇_max, q̇_max)`` [rad/s] into ``out``."""
        np.copyto(out.lower, self._negative)
        np.copyto(out.upper, self.speed)
        return out
