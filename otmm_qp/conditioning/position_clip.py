r"""Clipping q to the position limits in the integrator, as a command stage.

.. math::
    \dot q \leftarrow \frac{\operatorname{clip}(\tilde\theta + \dot q\,dt,\ \theta_{lo},
    \theta_{hi}) - \tilde\theta}{dt}

on the joint coordinates :math:`\tilde\theta` the controller sees: the Euler step that
follows lands exactly on the clipped position (for the ideal plant and joints whose
integration is a sum — revolute, prismatic — this *is* clipping q in the integrator; under
a lagging, delayed or simulated plant it is a clip of the commanded step, and the true q
can still pass a limit, which the metrics count). Unbounded joints are unchanged.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from otmm_qp.conditioning.stage import CommandStage
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.validation import Constraints

__all__ = ["PositionClipStage"]


class PositionClipStage(CommandStage):
    """Shorten each joint's step so that ``θ + q̇ dt`` stays within the position limits."""

    name: ClassVar[str] = "position_clip"
    parameter_constraints: ClassVar[Constraints] = {}

    def reset(self, robot: Robot, dt: float) -> None:
        """Read the robot's position limits [rad or m]."""
        super().reset(robot, dt)
        self.lower, self.upper = (np.asarray(b, dtype=float) for b in robot.position_limits)

    def apply(self, q: FloatArray, qdot: FloatArray) -> FloatArray:
        """The command whose Euler step ends inside ``[lower, upper]``."""
        theta = self.robot.joint_coordinates(q)
        target = theta + qdot * self.dt
        clipped = np.clip(target, self.lower, self.upper)
        if np.array_equal(clipped, target):
            return qdot
        return np.asarray((clipped - theta) / self.dt, dtype=float)
