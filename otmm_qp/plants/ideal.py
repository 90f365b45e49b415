r"""The ideal plant: the command is integrated exactly and the state is measured exactly.

.. math:: q_{k+1} = q_k \oplus \dot q_k\,dt,\qquad \tilde q_k = q_k

This is otmm-qp's behaviour before plants existed, and the default.
"""

from __future__ import annotations

from typing import ClassVar

from otmm_qp.plants.plant import Plant, PlantStep
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.validation import Constraints

__all__ = ["IdealPlant"]


class IdealPlant(Plant):
    """Explicit Euler body through :meth:`Robot.integrate`; no lag, no delay, no noise."""

    name: ClassVar[str] = "ideal"
    body: ClassVar[bool] = True
    parameter_constraints: ClassVar[Constraints] = {}

    def __init__(self) -> None:
        self._robot: Robot | None = None
        self._dt = 0.0

    def reset(self, robot: Robot, q0: FloatArray, dt: float) -> None:
        """Remember the robot and the period [s] (the body keeps no other state)."""
        self._robot = robot
        self._dt = dt

    def advance(self, q: FloatArray, qdot: FloatArray) -> PlantStep:
        r""":math:`q_{k+1} = q_k \oplus \dot q_k dt`; the actual velocity is the command."""
        if self._robot is None:
            raise RuntimeError("IdealPlant.advance called before reset")
        return PlantStep(self._robot.integrate(q, qdot, self._dt), qdot)
