r"""The joint-position limit as a velocity box: ``(g/dt)(θ_min − θ) ≤ q̇ ≤ (g/dt)(θ_max − θ)``."""

from __future__ import annotations

from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.limits.limit import Box, Limit
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.validation import Constraints, Interval, check_params

__all__ = ["PositionLimit"]


class PositionLimit(Limit):
    r"""Each step may close at most the fraction ``g`` of the distance to a position limit.

    .. math:: \frac{g}{dt}(\theta_{min} - \theta) \le \dot q \le \frac{g}{dt}(\theta_{max} - \theta)

    (pink's and mink's ``ConfigurationLimit`` with ``gain = g``). Infinite limits give infinite
    bounds (θ is finite and ``g/dt > 0``: no NaN can arise). Beyond a limit the box excludes
    ``q̇ = 0`` and, relaxed, asks the joint to move back. Priority 1.

    Args:
        gain: ``g ∈ (0, 1]`` [-] (``1``: the limit may be reached in one step).

    Raises:
        ParameterError: ``gain`` outside (0, 1] or not a number.
    """

    name: ClassVar[str] = "position"
    priority: ClassVar[int] = 1
    parameter_constraints: ClassVar[Constraints] = {"gain": Interval(Real, 0, 1, closed="right")}

    def __init__(self, gain: float = 0.5) -> None:
        check_params(self, locals())
        self.gain = float(gain)

    def bind(self, robot: Robot, dt: float) -> None:
        """Read ``[θ_min; θ_max]`` (shape ``(2, nv)``) and ``g/dt`` [1/s]."""
        super().bind(robot, dt)
        nv = robot.nv
        self._theta: FloatArray = np.array(robot.position_limits, dtype=float).reshape(2, nv)
        self._rate = self.gain / dt
        # Row views made once: a per-step (2, nv) − (nv,) broadcast allocates an iterator.
        self._theta_min, self._theta_max = self._theta[0], self._theta[1]

    def compute_box(self, theta: FloatArray, qdot_prev: FloatArray, out: Box) -> Box:
        """``((g/dt)(θ_min − θ), (g/dt)(θ_max − θ))`` [rad/s] into ``out``."""
        rate = self._rate
        np.subtract(self._theta_min, theta, out.lower)
        np.multiply(out.lower, rate, out.lower)
        np.subtract(self._theta_max, theta, out.upper)
        np.multiply(out.upper, rate, out.upper)
        return out
