r"""The joint-position limit as a velocity box: ``(g/dt)(θ_min − θ) ≤ q̇ ≤ (g/dt)(θ_max − θ)``."""

from __future__ import annotations

from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.limits.jerk_stopping import JerkStoppingBound
from otmm_qp.limits.limit import Box, Limit
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.validation import Constraints, Interval, check_params

__all__ = ["PositionLimit", "StoppingBound"]


class StoppingBound:
    r"""The fastest command that braking at :math:`a` can still stop within a distance.

    After the command :math:`v` the rest state moves :math:`v\,dt`, then each later command
    drops by :math:`s = a\,dt`: the travel is at most :math:`v\,dt + v^2/(2a)` (the sum of the
    steps lies below the integral), so :math:`v \le \beta(D) = -s + \sqrt{s^2 + 2a\max(D,0)}`
    [rad/s] stops within :math:`D` [rad]; braking at :math:`a` from a :math:`v \le \beta(D)`
    keeps :math:`v - s \le \beta(D - v\,dt)` (the proof in
    :mod:`otmm_qp.limits.command_limit`).

    Args:
        acceleration: :math:`a` > 0 [rad/s²], shape ``(nv,)`` (inf: that joint unbounded).
        dt: Control period [s].
    """

    def __init__(self, acceleration: FloatArray, dt: float) -> None:
        finite = np.isfinite(acceleration)
        self.step: FloatArray = np.where(finite, acceleration * dt, np.inf)
        self._s = np.where(finite, acceleration * dt, 0.0)
        self._s2 = self._s**2
        self._2a = np.where(finite, 2.0 * acceleration, 0.0)
        self._free = np.where(finite, 0.0, np.inf)
        self._bound: FloatArray = np.empty(acceleration.shape)

    def __call__(self, distance: FloatArray) -> FloatArray:
        r""":math:`\beta(D)` [rad/s] (nv,) of ``distance`` [rad] (nv,) (inf: no limit).

        Written into a scratch array valid until the next call.
        """
        bound = self._bound
        np.maximum(distance, 0.0, out=bound)
        bound *= self._2a
        bound += self._s2
        np.sqrt(bound, out=bound)
        bound -= self._s
        bound += self._free
        return bound


class PositionLimit(Limit):
    r"""Each step may close at most the fraction ``g`` of the distance to a position limit.

    .. math:: \frac{g}{dt}(\theta_{min} - \theta) \le \dot q \le \frac{g}{dt}(\theta_{max} - \theta)

    (pink's and mink's ``ConfigurationLimit`` with ``gain = g``). With a command limit in the
    same box (:meth:`brake_with`) the stopping distance :class:`StoppingBound` is added on
    both sides, :math:`-\beta(\theta - \theta_{min}) \le \dot q \le \beta(\theta_{max} -
    \theta)`; with a jerk limit too, the gain box is dropped within the limits
    (:math:`\beta(d) \le d/dt` keeps them; the gain box's geometric approach needs a jump of
    the acceleration every step) and the jerk-limited stopping distance is a soft box.
    Infinite limits give infinite bounds (θ is finite and ``g/dt > 0``: no NaN can arise).
    Beyond a limit the box excludes ``q̇ = 0`` and, relaxed, asks the joint to move back.
    Priority 1.

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
        self._stop: StoppingBound | None = None
        self._jerk_stop: JerkStoppingBound | None = None
        self._room: FloatArray = np.empty(nv)
        self._last: FloatArray = np.zeros(nv)

    def brake_with(
        self,
        acceleration: FloatArray,
        jerk_step: FloatArray | None = None,
        soft: Box | None = None,
    ) -> None:
        """Add the stopping distance at ``acceleration`` [rad/s²] (nv,) to the box.

        With ``jerk_step`` :math:`J` [rad/s] (nv,), every value finite, and ``soft`` (a soft
        limit's box), the jerk-limited stopping distance (:mod:`otmm_qp.limits.jerk_stopping`)
        is written into ``soft`` each step: a box given up before the jerk box, after the
        acceleration box (a joint whose two sides cross gets ±inf there).
        """
        self._stop = StoppingBound(acceleration, self.dt)
        finite = jerk_step is not None and bool(
            np.all(np.isfinite(acceleration)) and np.all(np.isfinite(jerk_step))
        )
        if finite and soft is not None:
            assert jerk_step is not None
            speed = np.array(self.robot.velocity_limits, dtype=float)
            self._jerk_stop = JerkStoppingBound(acceleration, jerk_step, self.dt, speed)
            self._soft_stop = soft

    def reset(self) -> None:
        """The arm at rest (the jerk-limited stopping distance reads the last increment)."""
        if hasattr(self, "_last"):
            self._last.fill(0.0)

    def compute_box(self, theta: FloatArray, qdot_prev: FloatArray, out: Box) -> Box:
        """``((g/dt)(θ_min − θ), (g/dt)(θ_max − θ))`` [rad/s] into ``out``."""
        rate = self._rate
        np.subtract(self._theta_min, theta, out.lower)
        np.multiply(out.lower, rate, out.lower)
        np.subtract(self._theta_max, theta, out.upper)
        np.multiply(out.upper, rate, out.upper)
        jerk_stop = self._jerk_stop
        if jerk_stop is not None:
            increment = qdot_prev - self._last
            np.copyto(self._last, qdot_prev)
            upper = jerk_stop.bound(self._theta_max - theta, qdot_prev, increment)
            lower = -jerk_stop.bound(theta - self._theta_min, -qdot_prev, -increment)
            crossed = lower > upper
            np.copyto(self._soft_stop.upper, np.where(crossed, np.inf, upper))
            np.copyto(self._soft_stop.lower, np.where(crossed, -np.inf, lower))
            # Within the limits the stopping distance keeps them (β(d) ≤ d/dt): the gain box,
            # whose geometric approach asks for a jump of the acceleration each step, is
            # kept only beyond a limit (to move back).
            out.upper[out.upper >= 0.0] = np.inf
            out.lower[out.lower <= 0.0] = -np.inf
        stop = self._stop
        if stop is not None:
            room = self._room
            np.subtract(self._theta_max, theta, out=room)
            np.minimum(out.upper, stop(room), out=out.upper)
            np.subtract(theta, self._theta_min, out=room)
            bound = stop(room)
            np.negative(bound, out=bound)
            np.maximum(out.lower, bound, out=out.lower)
        return out
