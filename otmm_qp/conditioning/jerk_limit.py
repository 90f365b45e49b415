r"""Acceleration- and jerk-limited joint-velocity commands, through Ruckig's velocity interface.

Every step the stage asks Ruckig (Berscheid & Kröger 2021, the time-optimal online
trajectory generator MoveIt Servo and many drivers use) for the jerk-limited motion from the
current joint velocity and acceleration to the commanded velocity, and sends the velocity
that motion reaches one control period later:

.. math::
    |\ddot q_i(t)| \le a_{max,i},\quad |\dddot q_i(t)| \le j_{max,i}
    \ \Rightarrow\ |\dot q_k - \dot q_{k-1}| \le a_{max}\,dt,\quad
    |\dot q_k - 2\dot q_{k-1} + \dot q_{k-2}| \le j_{max}\,dt^2

(the sampled bounds hold for the sequence sent, which is what the tests check). Ruckig is
used rather than our own jerk filter because its profiles are time-optimal and never
overshoot the target velocity; it starts at rest (zero velocity and acceleration).
"""

from __future__ import annotations

from numbers import Real
from typing import Any, ClassVar

import numpy as np

from otmm_qp.conditioning.stage import CommandStage
from otmm_qp.exceptions import ConfigError, DimensionError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.validation import ArrayOf, Constraints, Interval, check_params

__all__ = ["JerkLimitStage"]

RUCKIG_HINT = "pip install ruckig"


#: Limits Ruckig accepts [rad/s², rad/s³]: it raises on an acceleration or jerk below ~1e-12
#: (a 363-character ``RuckigError`` at step 0); the range is kept well inside.
RUCKIG_RANGE = (1e-6, 1e12)


def _limit(unit: str) -> ArrayOf:
    return ArrayOf(
        Interval(Real, RUCKIG_RANGE[0], RUCKIG_RANGE[1], unit=unit), scalar=True, per="joint"
    )


class JerkLimitStage(CommandStage):
    """Jerk- and acceleration-limited tracking of the velocity command (Ruckig).

    Args:
        acceleration: Acceleration limit a_max [rad/s²], one number or one per joint.
        jerk: Jerk limit j_max [rad/s³], one number or one per joint.

    Raises:
        ParameterError: A limit not finite and > 0.
        ConfigError: Ruckig is not installed (with the install hint).
    """

    name: ClassVar[str] = "jerk_limit"
    parameter_constraints: ClassVar[Constraints] = {
        "acceleration": _limit("rad/s²"),
        "jerk": _limit("rad/s³"),
    }

    def __init__(self, acceleration: float | list[float], jerk: float | list[float]) -> None:
        check_params(self, locals())
        try:
            import ruckig
        except ImportError:
            raise ConfigError("type", f"ruckig is not installed; {RUCKIG_HINT}") from None
        self._ruckig = ruckig
        self.acceleration = np.atleast_1d(np.asarray(acceleration, dtype=float))
        self.jerk = np.atleast_1d(np.asarray(jerk, dtype=float))
        self._generator: Any = None

    def reset(self, robot: Robot, dt: float) -> None:
        """A Ruckig generator at period ``dt`` [s], the joints at rest.

        Raises:
            DimensionError: A per-joint limit list not of length ``nv``.
        """
        super().reset(robot, dt)
        ruckig, nv = self._ruckig, robot.nv
        limits = {}
        for name, value in (("acceleration", self.acceleration), ("jerk", self.jerk)):
            if value.size not in (1, nv):
                raise DimensionError(name, (nv,), value.shape)
            limits[name] = np.broadcast_to(value, (nv,)).astype(float)
        self._generator = ruckig.Ruckig(nv, dt)
        self._input = ruckig.InputParameter(nv)
        self._output = ruckig.OutputParameter(nv)
        self._input.control_interface = ruckig.ControlInterface.Velocity
        self._input.current_position = [0.0] * nv
        self._input.current_velocity = [0.0] * nv
        self._input.current_acceleration = [0.0] * nv
        self._input.target_acceleration = [0.0] * nv
        self._input.max_velocity = [1e9] * nv  # unused by the velocity interface
        self._input.max_acceleration = limits["acceleration"].tolist()
        self._input.max_jerk = limits["jerk"].tolist()

    def apply(self, q: FloatArray, qdot: FloatArray) -> FloatArray:
        """The velocity (nv,) [rad/s] of the jerk-limited motion towards ``qdot`` after ``dt``."""
        self._input.target_velocity = np.asarray(qdot, dtype=float).tolist()
        result = self._generator.update(self._input, self._output)
        if result not in (self._ruckig.Result.Working, self._ruckig.Result.Finished):
            # Ruckig refuses (e.g. a target it cannot express): hold the current velocity,
            # which respects both bounds.
            return np.array(self._input.current_velocity, dtype=float)
        self._output.pass_to_input(self._input)
        return np.array(self._output.new_velocity, dtype=float)

    def label(self) -> str:
        """``jerk_limit(a=…,j=…)``."""
        a = ",".join(f"{v:g}" for v in self.acceleration)
        j = ",".join(f"{v:g}" for v in self.jerk)
        return f"{self.name}(a={a},j={j})"
