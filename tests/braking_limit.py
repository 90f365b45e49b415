r"""The worked example of ``docs/architecture.md``: a new limit is one class.

A braking-distance limit (pink's ``AccelerationLimit`` braking term): moving toward a position
limit, joint ``i`` must still be able to stop before it with deceleration ``a_max``,

.. math:: -\sqrt{2a_{max}\max(\theta_i - \theta_{min,i}, 0)} \le \dot q_i
          \le \sqrt{2a_{max}\max(\theta_{max,i} - \theta_i, 0)}

(``v²/(2a) ≤ d``). Infinite limits give infinite bounds.
"""

from __future__ import annotations

from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.limits import Box, Limit
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.validation import Constraints, Interval, check_params


class BrakingDistanceLimit(Limit):
    """``|q̇_i| ≤ √(2 a_max d_i)`` toward each position limit, ``d_i`` its distance [rad].

    Args:
        a_max: Deceleration available to stop [rad/s²], finite and > 0.

    Raises:
        ParameterError: ``a_max`` is not a finite number > 0.
    """

    name: ClassVar[str] = "braking_distance"
    priority: ClassVar[int] = 1  # given up with the position limit, before acceleration
    parameter_constraints: ClassVar[Constraints] = {
        "a_max": Interval(Real, 0, None, closed="neither", unit="rad/s²"),
    }

    def __init__(self, a_max: float = 10.0) -> None:
        check_params(self, locals())
        self.a_max = float(a_max)

    def bind(self, robot: Robot, dt: float) -> None:
        """Read ``θ_min``, ``θ_max`` [rad], shapes ``(nv,)``."""
        super().bind(robot, dt)
        low, high = robot.position_limits
        self._low = np.array(low, dtype=float)
        self._high = np.array(high, dtype=float)

    def compute_box(self, theta: FloatArray, qdot_prev: FloatArray, out: Box) -> Box:
        """``(−√(2a(θ − θ_min)⁺), √(2a(θ_max − θ)⁺))`` [rad/s] into ``out``."""
        np.subtract(theta, self._low, out=out.lower)
        np.subtract(self._high, theta, out=out.upper)
        for side in out:
            np.maximum(side, 0.0, out=side)
            np.multiply(side, 2.0 * self.a_max, out=side)
            np.sqrt(side, out=side)
        np.negative(out.lower, out=out.lower)
        return out
