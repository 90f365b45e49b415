"""Straight lines: quintic ("bell-shaped" velocity) and constant velocity."""

from __future__ import annotations

import math
from collections.abc import Sequence
from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.exceptions import DimensionError, ParameterError
from otmm_qp.robots.robot import FloatArray
from otmm_qp.trajectories.trajectory import Trajectory
from otmm_qp.validation import ArrayOf, Constraints, Interval, check_params


class _Line(Trajectory):
    """Shared constructor of the lines: ``begin`` defaults to the start position."""

    #: A planned motion: known in full at any time (:attr:`Trajectory.lookahead`).
    lookahead = math.inf
    parameter_constraints: ClassVar[Constraints] = {
        "end": ArrayOf(Interval(Real, None, None, unit="m"), per="task coordinate"),
        "duration": Interval(Real, 0, None, closed="neither", unit="s"),
        "begin": [ArrayOf(Interval(Real, None, None, unit="m"), per="task coordinate"), None],
    }

    def __init__(
        self,
        start: FloatArray,
        end: Sequence[float],
        duration: float,
        begin: Sequence[float] | None = None,
    ) -> None:
        check_params(self, locals())
        self.end = np.asarray(end, dtype=float)
        dim = self.end.size
        if begin is None:
            start_value = np.asarray(start, dtype=float)
            if start_value.ndim == 2:
                start_value = start_value[:dim, 3]
            self.begin = start_value[:dim].copy()
        else:
            self.begin = np.asarray(begin, dtype=float)
        if self.begin.shape != self.end.shape:
            raise DimensionError("begin", self.end.shape, self.begin.shape)
        if not duration > 0.0:
            raise ParameterError("duration", f"must be > 0 [s], got {duration}")
        self.duration = float(duration)


class QuinticLineTrajectory(_Line):
    r"""Line from ``begin`` to ``end`` with a quintic (minimum-jerk) time law.

    .. math::
        x_d(t) = b + (e - b)\,s(\tau),\quad s = 10\tau^3 - 15\tau^4 + 6\tau^5,\quad \tau = t/T

    held at ``end`` for ``t > T``. This is the paper's Fig. 7 law.

    Args:
        start: Task value at the start configuration (used when ``begin`` is omitted).
        end: End point [m].
        duration: Motion time ``T`` [s].
        begin: Start point [m]; the start position when omitted.
    """

    name = "quintic_line"

    def sample(self, t: float) -> tuple[FloatArray, FloatArray]:
        """Position [m] and velocity [m/s] at ``t`` [s]."""
        tau = min(max(t / self.duration, 0.0), 1.0)
        s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)
        ds = 30.0 * tau**2 * (1.0 - tau) ** 2 / self.duration  # [1/s]
        if t < 0.0 or t > self.duration:
            ds = 0.0
        delta = self.end - self.begin
        return self.begin + s * delta, ds * delta


class ConstantVelocityLineTrajectory(_Line):
    r"""Line from ``begin`` to ``end`` at constant speed, held at ``end`` after ``T``.

    .. math:: x_d(t) = b + (e - b)\,\min(t/T, 1)
    """

    name = "constant_velocity_line"

    def sample(self, t: float) -> tuple[FloatArray, FloatArray]:
        """Position [m] and velocity [m/s] at ``t`` [s]."""
        tau = min(max(t / self.duration, 0.0), 1.0)
        moving = 0.0 <= t < self.duration
        delta = self.end - self.begin
        return self.begin + tau * delta, (delta / self.duration if moving else 0.0 * delta)
