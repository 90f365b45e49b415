r"""The command's acceleration and jerk as limits of the command, given up braking first.

A streaming interface that checks the command stream (the Franka FCI aborts a motion whose
commanded acceleration or jerk passes its thresholds, :mod:`otmm_qp.plants.interface`) needs
per joint, with the previous commands :math:`\dot q_{k-1}, \dot q_{k-2}` [rad/s]
(:math:`\dot q_{-1} = \dot q_{-2} = 0`: the arm starts at rest),

.. math::
    A_k:\ |\dot q - \dot q_{k-1}| \le a\,dt,\qquad
    J_k:\ |\dot q - 2\dot q_{k-1} + \dot q_{k-2}| \le j\,dt\,p

(:math:`a` [rad/s²], :math:`j` [rad/s³], :math:`p = \min(dt, \text{period})` [s] with the
interface's period the plant declares, else :math:`p = dt`: the jerk an interface faster than
the controller sees of a linearly interpolated command, :mod:`otmm_qp.plants.interface`).
These boxes are *soft* (:attr:`Limit.soft`): the
step's box is composed by :class:`~otmm_qp.limits.box.LimitBox` in the stated order

.. math::
    B_k = \mathrm{relax}(H_k, A_k, S_k, J_k)

with :math:`H_k` the hard boxes (velocity, position with the stopping distance below) and
:math:`S_k` the jerk-limited stopping distance (with a jerk limit only,
:mod:`otmm_qp.limits.jerk_stopping`): each next box is intersected when the intersection is
non-empty, else the current box shrinks, per joint, to its point nearest that box
(:func:`~otmm_qp.limits.box.relaxed`). So the jerk box is given up first, then the
jerk-limited stopping distance, then the acceleration box, never the position or velocity
box: the step
brakes as hard as the position limit needs and no harder, :math:`B_k \ne \emptyset` whenever
:math:`H_k \ne \emptyset`, and the backend reports ``relaxed`` instead of an infeasible QP.

**Stopping distance.** With a command limit, every position limit of the same box
(``position``, ``predicted_position``) adds the bound under which braking at :math:`a` still
stops before it (:meth:`~otmm_qp.limits.position_limit.PositionLimit.brake_with`): with
:math:`d^+ = \theta_{max} - m - \hat R_k` [rad] the distance of the (predicted) rest state to
the (shrunk) limit and :math:`s = a\,dt`,

.. math:: \dot q \le \beta(d^+) = -s + \sqrt{s^2 + 2a\max(d^+, 0)}

(and likewise below).

**Claim.** Let the position box be ``{position | predicted_position, gain: g}`` with
:math:`g \in [1/2, 1]`, without ``deceleration`` or ramp, the rest state move by the command,
:math:`\hat R_{k+1} = \hat R_k + \dot q_k\,dt` (the ideal plant; a latency or lag predicted by
``predicted_position``; no measurement noise), and :math:`\hat R_0` within the limits. Then

1. :math:`\hat R_k` never passes a position limit (the position box is hard: it is kept at
   every step, and :math:`g \le 1`);
2. the acceleration box holds at every step: :math:`H_k \cap A_k \ne \emptyset`.

Proof of 2 (upper side; the lower is symmetric). By induction, :math:`v = \dot q_{k-1} \in
H_{k-1}` (true for :math:`v = 0` at a start within the limits); write :math:`d = d^+_{k-1}`,
so :math:`d^+_k = d - v\,dt`. Need :math:`v - s \le \min(g\,d^+_k/dt,\ \beta(d^+_k))` (the
speed limit is constant, so braking keeps it).

* :math:`\beta`: if :math:`v \le s`, :math:`v - s \le 0 \le \beta`. Else :math:`v \le \beta(d)`
  gives :math:`v^2 + 2vs \le 2a\,d`, so :math:`v^2 \le s^2 + 2a(d - v\,dt)`, i.e.
  :math:`v - s \le \beta(d - v\,dt)`.
* the gain box: need :math:`v(1+g) \le g\,d/dt + s`. In units of :math:`s` with
  :math:`x = d/(a\,dt^2)`, :math:`v \le \min(gx, -1 + \sqrt{1 + 2x})`. If :math:`g^2 x \le 1`,
  :math:`gx(1+g) \le gx + 1`. Else the concave :math:`-1 + \sqrt{1+2x}` lies below the line
  :math:`(gx + 1)/(1+g)`: their largest difference,
  :math:`(1 - 2g)/(2g(1+g))`, at :math:`\sqrt{1+2x} = (1+g)/g`, is :math:`\le 0` for
  :math:`g \ge 1/2`. ∎

With a jerk limit the gain box is dropped within the limits (:math:`\beta(d) \le d/dt` keeps
them), so the claim holds for every :math:`g` (the first bullet is the whole proof). For
:math:`g < 1/2` without a jerk limit, a ``deceleration`` bound, a ramp, or measurement noise
the claim is not made: the composition above still keeps the position and speed limits and
relaxes the acceleration box only on the steps where it must. The jerk box holds whenever it
meets :math:`H_k \cap A_k \cap S_k`; :math:`S_k` keeps one jerk-limited brake available
toward each limit, but the two sides are not proven compatible together (a joint whose two
bounds cross gives :math:`S_k` up), so the jerk is measured, not claimed
(``tests/limits/test_command_limit.py``, the plants_franka study in docs/plants.md).

Per-joint limits come from the robot or the preset: ``plant`` (the default) reads what the
run's plant declares (:class:`~otmm_qp.plants.interface.InterfaceLimits`, the
``franka_fci_raw`` and ``fr3_fci`` presets); under a plant that declares no threshold the
``plant`` limit has nothing to keep and adds no box (a study's ``plants`` axis mixes both).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from otmm_qp.exceptions import ParameterError
from otmm_qp.limits.limit import Box, Limit, per_joint
from otmm_qp.plants.declaration import PlantDeclaration
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.validation import Boolean, Constraints, OneOf, check_params, positive_per_joint

__all__ = ["FROM_PLANT", "CommandLimit"]

#: The value that means "the interface thresholds the plant declares".
FROM_PLANT = "plant"


class CommandLimit(Limit):
    r"""Soft acceleration and jerk boxes around the previous commands (see the module).

    Args:
        acceleration: :math:`a` > 0 [rad/s²] (inf: that joint unlimited), a scalar or one per
            joint, or ``plant``: the interface threshold the plant declares (none declared:
            the limit adds no box).
        jerk: :math:`j` > 0 [rad/s³] likewise, ``plant`` (none when the plant declares none),
            or None: no jerk box.
        stopping: Whether the position limits of the same box add the stopping distance at
            :math:`a` (the claim of the module needs it).

    Raises:
        ParameterError: A value that is not > 0, NaN, or not ``plant``.
    """

    name: ClassVar[str] = "command"
    priority: ClassVar[int] = 2
    soft: ClassVar[bool] = True
    parameter_constraints: ClassVar[Constraints] = {
        "acceleration": [positive_per_joint("rad/s²"), OneOf(FROM_PLANT)],
        "jerk": [positive_per_joint("rad/s³"), OneOf(FROM_PLANT), None],
        "stopping": Boolean(),
    }

    def __init__(
        self,
        acceleration: float | Sequence[float] | str = FROM_PLANT,
        jerk: float | Sequence[float] | str | None = FROM_PLANT,
        stopping: bool = True,
    ) -> None:
        check_params(self, locals())
        self.acceleration = acceleration
        self.jerk = jerk
        self.stopping = bool(stopping)
        self.declared = PlantDeclaration()

    def declare_plant(self, declaration: PlantDeclaration) -> None:
        """Take the plant's interface thresholds (for values left at ``plant``)."""
        self.declared = declaration

    def limits(self, nv: int) -> tuple[FloatArray, FloatArray | None]:
        """``(a (nv,) [rad/s²], j (nv,) [rad/s³] or None)`` in force (inf: none declared).

        Raises:
            ParameterError: A jerk limit given without an acceleration limit to go with it.
            DimensionError: A value is neither a scalar nor one per joint.
        """
        acceleration = self.acceleration
        if isinstance(acceleration, str):  # FROM_PLANT
            declared = self.declared.interface_acceleration
            acceleration = declared or math.inf
            if not declared and not isinstance(self.jerk, str | None):
                raise ParameterError(
                    "jerk",
                    "needs an acceleration limit: give acceleration in rad/s² (the plant "
                    "declares none for acceleration: plant)",
                )
        jerk = self.jerk
        if isinstance(jerk, str):  # FROM_PLANT
            jerk = self.declared.interface_jerk or None
        a = per_joint(_one(acceleration), "acceleration", nv)
        j = per_joint(_one(jerk), "jerk", nv)
        assert a is not None
        return a, j

    def bind(self, robot: Robot, dt: float) -> None:
        """``a·dt`` [rad/s] and ``j·dt²`` [rad/s] per joint; the history at rest."""
        super().bind(robot, dt)
        a, j = self.limits(robot.nv)
        #: Whether the limit adds a box (False: ``plant`` and nothing declared).
        self.active = bool(np.any(np.isfinite(a))) or j is not None
        #: The braking acceleration the position limits use [rad/s²], ``(nv,)``.
        self.braking: FloatArray | None = a if self.stopping and self.active else None
        self._step: FloatArray = a * dt
        period = self.declared.interface_period or dt
        self._jerk_step: FloatArray | None = None if j is None else j * dt * min(dt, period)
        #: The jerk step J [rad/s] the position limits' stopping distance respects.
        self.jerk_braking: FloatArray | None = self._jerk_step if self.braking is not None else None
        self._older: FloatArray = np.zeros(robot.nv)
        self._jerk = Box(np.empty(robot.nv), np.empty(robot.nv))
        #: The jerk-limited stopping distance the position limits write (±inf: none).
        self.stop_box: Box | None = Box(np.full(robot.nv, -np.inf), np.full(robot.nv, np.inf))
        self._started = False

    def reset(self) -> None:
        """The arm at rest: no command before the first."""
        self._started = False

    def secondary(self) -> tuple[Box, ...]:
        """The jerk-limited stopping distance, then the jerk box (none without a jerk limit).

        Given up in that order, after the acceleration box.
        """
        if self._jerk_step is None or self.stop_box is None:
            return ()
        return (self.stop_box, self._jerk)

    def compute_box(self, theta: FloatArray, qdot_prev: FloatArray, out: Box) -> Box:
        r"""``A_k`` into ``out`` and ``J_k`` into :meth:`secondary` [rad/s], shapes ``(nv,)``."""
        np.subtract(qdot_prev, self._step, out=out.lower)
        np.add(qdot_prev, self._step, out=out.upper)
        if not self._started:
            self._older.fill(0.0)
            self._started = True
        if self._jerk_step is not None:
            centre = self._jerk.lower
            np.multiply(qdot_prev, 2.0, out=centre)
            centre -= self._older  # 2q̇_{k−1} − q̇_{k−2}
            np.add(centre, self._jerk_step, out=self._jerk.upper)
            centre -= self._jerk_step
        np.copyto(self._older, qdot_prev)
        return out


def _one(value: float | Sequence[float] | None) -> float | Sequence[float] | None:
    """A one-value declaration as a scalar (a tuple of one applies to every joint)."""
    if isinstance(value, tuple) and len(value) == 1:
        return float(value[0])
    return value
