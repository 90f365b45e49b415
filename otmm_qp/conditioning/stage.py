r"""Output conditioning: what an arm's driver does to a joint-velocity command before the servos.

A conditioning *stage* maps the controller's command to the one sent on,
:math:`\dot q \leftarrow s(\tilde q, \dot q)`, on the configuration the controller sees
:math:`\tilde q`. Stages run in the order listed, after the controller and before the plant;
none runs by default. They apply to any controller (a loop option, not a backend option).
"""

from __future__ import annotations

import abc
from typing import ClassVar

from otmm_qp.robots.robot import FloatArray, Robot

__all__ = ["CommandStage"]


class CommandStage(abc.ABC):
    """One conditioning stage; :meth:`reset` at the start of a run, :meth:`apply` every step."""

    #: Registered name (set by each stage).
    name: ClassVar[str] = "stage"

    def reset(self, robot: Robot, dt: float) -> None:
        """Start a run on ``robot`` with control period ``dt`` [s] (default: remember both).

        Raises:
            ConfigError: A parameter does not fit the robot (e.g. a limit list of the wrong
                length); raised when the run is prepared, before any step.
        """
        self.robot = robot
        self.dt = dt

    @abc.abstractmethod
    def apply(self, q: FloatArray, qdot: FloatArray) -> FloatArray:
        """The conditioned command (nv,) [rad/s] of ``qdot`` (nv,) at configuration ``q`` (nq,)."""

    def label(self) -> str:
        """Short label with the parameters, e.g. ``jerk_limit(a=5,j=50)``."""
        return self.name
