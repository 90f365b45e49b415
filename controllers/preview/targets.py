r"""What each knot still misses: the residuals :math:`\bar r_i` of the preview QP.

Two sources of the horizon's targets, the one difference between the preview backend and its
causal counterpart (same QP, same nominal, same Jacobians):

* :class:`TrajectoryTargets` (preview): the desired path itself,
  :math:`\bar r_i = W\,e(x_d(t + \tau_i), x(\bar\theta_i))`;
* :class:`HeldCommandTargets` (causal): the horizon filled by holding the present command
  :math:`\dot x_w` (weighted, after the filters), the target displacement from the present
  task value :math:`x_0` being :math:`\tau_i\dot x_w`:
  :math:`\bar r_i = \tau_i\dot x_w - W\,e(x(\bar\theta_i), x_0)`.

``e(a, b)`` is :meth:`Robot.task_error` (``a ⊖ b``: a difference, or the log map for poses).
"""

from __future__ import annotations

import abc
import math

import numpy as np

from otmm_qp.exceptions import NonFiniteState
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.trajectories.trajectory import Trajectory

__all__ = ["HeldCommandTargets", "Targets", "TrajectoryTargets"]


class Targets(abc.ABC):
    """The residuals of the horizon's knots at one step."""

    @abc.abstractmethod
    def residuals(
        self,
        robot: Robot,
        state: KinematicState,
        xdot: FloatArray,
        t: float,
        knots: list[FloatArray],
        out: FloatArray,
        start: int = 0,
    ) -> FloatArray:
        r"""Write :math:`\bar r_i` [weighted task units] of the given knots into ``out``.

        Rows ``start … start + len(knots) − 1`` of ``out`` (shape ``(K, n)``) are written.

        Args:
            robot: The arm (its task error).
            state: The step's state (``x_0``, the weight ``W``).
            xdot: The weighted command ``ẋ_w``, shape ``(n,)``.
            t: Present time [s].
            knots: The task values :math:`x(\bar\theta_i)` of those nominal knots.
            out: Array of shape ``(K, n)``.
            start: Index ``i`` of the first of ``knots``.

        Raises:
            NonFiniteState: A target is NaN or inf.
        """

    @abc.abstractmethod
    def speed(self, robot: Robot, state: KinematicState, xdot: FloatArray, t: float) -> float:
        r"""The window's task speed :math:`\bar v` [weighted task units/s] at time ``t`` [s].

        The rule of ``peak_scale: arm`` (:mod:`.parameters`); finite and ≥ 0.
        """


class TrajectoryTargets(Targets):
    """The desired path ``x_d(t + τ_i)`` at the knot offsets (preview).

    Args:
        trajectory: A motion whose ``lookahead`` covers the horizon.
        taus: Knot offsets ``τ_1 … τ_K`` [s], shape ``(K,)``.
    """

    def __init__(self, trajectory: Trajectory, taus: FloatArray) -> None:
        self.trajectory = trajectory
        self.taus = [float(tau) for tau in taus]
        # x_d(t) and x_d(t + H) of the last residuals at time t (for speed: no second call).
        self._ends: tuple[float, FloatArray | None, FloatArray | None] = (math.nan, None, None)

    def residuals(
        self,
        robot: Robot,
        state: KinematicState,
        xdot: FloatArray,
        t: float,
        knots: list[FloatArray],
        out: FloatArray,
        start: int = 0,
    ) -> FloatArray:
        r""":math:`\bar r_i = W\,e(x_d(t + \tau_i), x(\bar\theta_i))`."""
        error, weight = robot.task_error, state.weight
        stop = start + len(knots)
        times = [t + tau for tau in self.taus[start:stop]]
        if start == 0:  # x_d(t) too, in the same vectorised call (speed's chord start)
            now, *desired = self.trajectory.positions([t, *times])
            self._ends = (t, now, None)
        else:
            desired = self.trajectory.positions(times)
        if stop == len(self.taus) and self._ends[0] == t:
            self._ends = (t, self._ends[1], desired[-1])
        for i, target, x in zip(range(start, stop), desired, knots, strict=True):
            np.multiply(weight, error(target, x), out=out[i])
        if not math.isfinite(float(out[start:stop].sum())):
            raise NonFiniteState(
                "trajectory", f"x_d is NaN or inf within the preview window after t = {t:g} s"
            )
        return out

    def speed(self, robot: Robot, state: KinematicState, xdot: FloatArray, t: float) -> float:
        r""":math:`\bar v = \|W\,e(x_d(t + H), x_d(t))\| / H`, the window's chord speed."""
        horizon = self.taus[-1]
        when, now, ahead = self._ends
        if when != t or now is None or ahead is None:  # no residuals at t: evaluate both ends
            now, ahead = self.trajectory.positions([t, t + horizon])
        value = float(np.linalg.norm(state.weight * robot.task_error(ahead, now))) / horizon
        return value if math.isfinite(value) else 0.0  # a NaN path is refused by residuals


class HeldCommandTargets(Targets):
    r"""The present command held over the horizon (causal): :math:`\tau_i\dot x_w` from ``x_0``.

    Args:
        taus: Knot offsets ``τ_1 … τ_K`` [s], shape ``(K,)``.
    """

    def __init__(self, taus: FloatArray) -> None:
        self.taus = np.asarray(taus, dtype=float)

    def residuals(
        self,
        robot: Robot,
        state: KinematicState,
        xdot: FloatArray,
        t: float,
        knots: list[FloatArray],
        out: FloatArray,
        start: int = 0,
    ) -> FloatArray:
        r""":math:`\bar r_i = \tau_i\dot x_w - W\,e(x(\bar\theta_i), x_0)`."""
        stop = start + len(knots)
        np.multiply(self.taus[start:stop, None], xdot, out=out[start:stop])
        error, weight, x0 = robot.task_error, state.weight, state.x
        for i, x in enumerate(knots, start):
            out[i] -= weight * error(x, x0)
        return out

    def speed(self, robot: Robot, state: KinematicState, xdot: FloatArray, t: float) -> float:
        r""":math:`\bar v = \|\dot x_w\|`, the held command's speed."""
        value = float(np.linalg.norm(xdot))
        return value if math.isfinite(value) else 0.0
