r"""Command latency: the command reaches the servos ``steps`` control periods late.

.. math:: \dot q^{a}_k = \dot q^{cmd}_{k-N},\qquad \dot q^{cmd}_{j<0} = 0

``steps: 0`` is the ideal plant.
"""

from __future__ import annotations

from collections import deque
from numbers import Integral
from typing import ClassVar

import numpy as np

from otmm_qp.plants.declaration import PlantDeclaration
from otmm_qp.plants.plant import Plant
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.validation import Constraints, Interval, check_params

__all__ = ["DelayPlant"]


class DelayPlant(Plant):
    """A FIFO of the last ``steps`` commands, starting full of zeros (the arm at rest).

    Args:
        steps: Latency N in control periods, an integer >= 0.
    """

    name: ClassVar[str] = "delay"
    parameter_constraints: ClassVar[Constraints] = {
        "steps": Interval(Integral, 0, None, closed="left"),
    }

    def __init__(self, steps: int = 1) -> None:
        check_params(self, locals())
        self.steps = int(steps)
        self._queue: deque[FloatArray] = deque()

    def reset(self, robot: Robot, q0: FloatArray, dt: float) -> None:
        """Fill the FIFO with ``steps`` zero commands."""
        self._queue = deque(np.zeros(robot.nv) for _ in range(self.steps))

    def command(self, qdot: FloatArray) -> FloatArray:
        """The command received ``steps`` periods ago [rad/s]; ``qdot`` joins the queue."""
        if self.steps == 0:
            return qdot
        self._queue.append(np.array(qdot, dtype=float))
        return self._queue.popleft()

    def declares(self, dt: float) -> PlantDeclaration:
        """The latency N [periods]."""
        return PlantDeclaration(delay=self.steps)

    def label(self) -> str:
        """``delay(steps=N)``."""
        return f"delay(steps={self.steps})"
