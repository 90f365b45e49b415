r"""The fastest command from which a jerk-limited brake still stops before a limit.

With a jerk limit the command cannot switch from accelerating to braking in one step: the
increment :math:`\delta_k = \dot q_k - \dot q_{k-1}` [rad/s] may change by at most
:math:`J = j\,dt\,p` per step and stays within :math:`\pm A`, :math:`A = a\,dt`
(:mod:`otmm_qp.limits.command_limit`). The *brake* from a command :math:`v` with increment
:math:`\delta` is the sequence

.. math::
    \delta_{i} = \max(\delta_{i-1} - J, -A),\qquad v_i = v_{i-1} + \delta_i\quad(i \ge 1)

(the steepest admissible deceleration); the rest state moves :math:`v_i\,dt` each step. For a
distance :math:`D` [rad] to the limit and the speed limit :math:`\bar v` the command :math:`v`
is *safe* when every command of the brake from :math:`(v, v - \dot q_{k-1})` keeps the
acceleration-only stopping bound :math:`\beta`
(:class:`~otmm_qp.limits.position_limit.StoppingBound`) at the distance left before it, and
the speed limit:

.. math:: v_i \le \beta\big(D - dt\textstyle\sum_{m<i} v_m\big),\qquad v_i \le \bar v.

Once the increment is :math:`-A` the brake is the acceleration-only one, which keeps
:math:`\beta` (:mod:`otmm_qp.limits.command_limit`), so the check stops there; and a safe
command is within :math:`\beta(D)`, the hard bound: the soft jerk-limited bound never asks for
more than the hard one allows.

**Invariance.** The brake from :math:`(v_1, \delta_1)` is the tail of the brake from
:math:`(v, \delta)`, and the distance after the step is :math:`D - v\,dt`: if :math:`v_k` is
safe, its brake's first command :math:`v_{k+1}` is safe at step :math:`k+1`, and it lies in
the acceleration and jerk boxes. Safety is monotone in :math:`v` (a larger command has a
larger increment, so every later velocity of its brake is larger), so the safe commands of a
step are :math:`v \le v^*`; :class:`JerkStoppingBound` finds :math:`v^*` within the boxes by a
two-level grid search (17 points each, vectorised over the joints: the bound it returns is
safe, and within :math:`(2A + 2J)/16^2` of :math:`v^*`).
"""

from __future__ import annotations

import numpy as np

from otmm_qp.robots.robot import FloatArray

__all__ = ["JerkStoppingBound"]

#: Points of each level of the grid search.
GRID = 17
_FRACTIONS = np.linspace(0.0, 1.0, GRID)[:, None]


class JerkStoppingBound:
    r"""The largest safe command :math:`v^*` [rad/s] toward a limit (see the module).

    Args:
        acceleration: :math:`a` > 0 [rad/s²], shape ``(nv,)`` (finite).
        jerk_step: :math:`J = j\,dt\,p` > 0 [rad/s], shape ``(nv,)`` (finite).
        dt: Control period [s].
        speed: Speed limit :math:`\bar v` [rad/s], shape ``(nv,)`` (inf: none).
    """

    def __init__(
        self, acceleration: FloatArray, jerk_step: FloatArray, dt: float, speed: FloatArray
    ) -> None:
        self.step = acceleration * dt
        self.jerk = jerk_step
        self.dt = dt
        self.speed = speed
        self._ramp = int(np.max(np.ceil(2.0 * self.step / self.jerk))) + 2

    def bound(
        self, distance: FloatArray, previous: FloatArray, increment: FloatArray
    ) -> FloatArray:
        r""":math:`v^*` [rad/s] (nv,) toward the limit ``distance`` [rad] (nv,) away.

        Args:
            distance: :math:`D` [rad], shape ``(nv,)`` (≤ 0: beyond the limit).
            previous: :math:`\dot q_{k-1}` [rad/s], shape ``(nv,)``.
            increment: :math:`\dot q_{k-1} - \dot q_{k-2}` [rad/s], shape ``(nv,)``.

        Returns:
            The largest safe command in the boxes; the steepest brake
            :math:`\dot q_{k-1} + \max(\delta - J, -A)` where none is safe.
        """
        low = previous + np.maximum(increment - self.jerk, -self.step)
        high = previous + np.minimum(increment + self.jerk, self.step)
        for _ in range(2):
            grid = low + _FRACTIONS * (high - low)  # (GRID, nv)
            safe = self._safe(grid, previous, distance)
            last = GRID - 1 - np.argmax(safe[::-1], axis=0)  # largest safe index
            none = ~safe.any(axis=0)
            index = np.where(none, 0, last)
            columns = np.arange(grid.shape[1])
            new_low = grid[index, columns]
            new_high = grid[np.minimum(index + 1, GRID - 1), columns]
            low = new_low
            high = np.where(none | (index == GRID - 1), new_low, new_high)
        return low

    def _safe(self, v: FloatArray, previous: FloatArray, distance: FloatArray) -> np.ndarray:
        """Whether each candidate command ``v`` (K, nv) is safe (see the module)."""
        dt, step, jerk = self.dt, self.step, self.jerk
        two_a = 2.0 * step / dt
        delta = v - previous
        velocity = v.copy()
        room = np.broadcast_to(distance, v.shape).copy()  # D − travel before the step
        safe = np.ones(v.shape, dtype=bool)
        for _ in range(self._ramp + 1):  # until the increment reaches −A
            beta = np.sqrt(step * step + two_a * np.maximum(room, 0.0)) - step
            safe &= (velocity <= beta * (1.0 + 1e-12) + 1e-15) & (
                velocity <= self.speed * (1.0 + 1e-12)
            )
            room = room - velocity * dt
            delta = np.maximum(delta - jerk, -step)
            velocity = velocity + delta
        return safe
