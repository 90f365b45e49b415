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


#: Longest delay [control periods] (a queue of that many commands is allocated at reset).
MAX_STEPS = 100_000
#: Memory of one queued command per joint [bytes], about (array header amortised).
BYTES_PER_STEP = 24
_MEMORY = (
    f"periods; the queue holds one command per period, ~{BYTES_PER_STEP} bytes per joint: "
    f"{MAX_STEPS} periods ≈ {MAX_STEPS * BYTES_PER_STEP * 7 / 2**20:.0f} MiB on 7 joints"
)


class DelayPlant(Plant):
    """A FIFO of the last ``steps`` commands, starting full of zeros (the arm at rest).

    Args:
        steps: Latency N in control periods, an integer >= 0.
    """

    name: ClassVar[str] = "delay"
    parameter_constraints: ClassVar[Constraints] = {
        "steps": Interval(Integral, 0, MAX_STEPS, unit=_MEMORY),
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
