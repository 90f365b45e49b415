r"""Rate limiter on the command path: each joint's commanded velocity changes at most ``a·dt``.

The streaming interface of an arm that refuses (or reflexes on) commands its drives cannot
follow limits the command's acceleration before it reaches the joint controllers — libfranka's
``limitRate`` (its per-joint limits 15, 7.5, 10, 12.5, 15, 20, 20 rad/s² on the Panda), a
UR's ``speedj`` acceleration argument. Once per control period:

.. math::
    v_k = v_{k-1} + \operatorname{clip}(u_k - v_{k-1},\ -a\,dt,\ a\,dt)

(:math:`u_k` [rad/s] the incoming command, :math:`v_k` the limited one passed on, :math:`a`
[rad/s²] per joint, :math:`v_{-1} = 0`: the arm starts at rest). A joint with :math:`a = \infty`
passes its command unchanged.

The limiter acts once per control period: libfranka runs it every 1 ms, so a controller at a
slower rate that holds its command sees the same limited value at the period's end; the jerk
limits libfranka adds (3,750–10,000 rad/s³ on the Panda) reach a·dt within
:math:`a/j_{max} \le 2.7` ms and are not modelled. The stage declares :math:`a`
(:mod:`otmm_qp.plants.declaration`), so a controller's ``predicted_position`` limit runs the
same limiter on its own commands and bounds the travel the limiter needs to stop.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from otmm_qp.plants.declaration import PlantDeclaration
from otmm_qp.plants.plant import Plant
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.validation import Constraints, check_params, per_joint, positive_per_joint

__all__ = ["RateLimitPlant", "rate_limit_step"]


def rate_limit_step(
    command: FloatArray, previous: FloatArray, step: FloatArray, out: FloatArray
) -> FloatArray:
    r""":math:`v_k = v_{k-1} + \operatorname{clip}(u_k - v_{k-1}, -a\,dt, a\,dt)` into ``out``.

    Args:
        command: :math:`u_k` [rad/s], shape ``(nv,)``.
        previous: :math:`v_{k-1}` [rad/s], shape ``(nv,)``.
        step: :math:`a\,dt` [rad/s] per joint, shape ``(nv,)`` (inf: no limit).
        out: Where :math:`v_k` goes, shape ``(nv,)`` (may be ``previous``).
    """
    change = np.subtract(command, previous)
    np.clip(change, -step, step, out=change)
    return np.add(previous, change, out=out)


class RateLimitPlant(Plant):
    r"""Acceleration limit on the velocity command (see the module).

    Args:
        acceleration: :math:`a` > 0 [rad/s²] (inf: that joint unlimited), a scalar or one per
            joint.

    Raises:
        ParameterError: A value that is not > 0 (naming it).
    """

    name: ClassVar[str] = "rate_limit"
    parameter_constraints: ClassVar[Constraints] = {
        "acceleration": positive_per_joint("rad/s²"),
    }

    def __init__(self, acceleration: float | Sequence[float]) -> None:
        check_params(self, locals())
        self.acceleration = acceleration
        self._step = np.zeros(0)
        self._last = np.zeros(0)

    def reset(self, robot: Robot, q0: FloatArray, dt: float) -> None:
        r"""Start at rest (:math:`v_{-1} = 0`) with :math:`a\,dt` for the period ``dt`` [s].

        Raises:
            DimensionError: ``acceleration`` is neither a scalar nor one value per joint.
        """
        limit = per_joint(self.acceleration, "acceleration", robot.nv)
        assert limit is not None
        self._step = limit * dt
        self._last = np.zeros(robot.nv)

    def command(self, qdot: FloatArray) -> FloatArray:
        """The limited command :math:`v_k` (nv,) [rad/s] of the incoming ``qdot`` (nv,)."""
        self._last = rate_limit_step(qdot, self._last, self._step, np.empty_like(self._last))
        return self._last

    def declares(self, dt: float) -> PlantDeclaration:
        """The limit :math:`a` [rad/s²] (one value, or one per joint)."""
        value = np.atleast_1d(np.asarray(self.acceleration, dtype=float))
        return PlantDeclaration(acceleration=tuple(float(x) for x in value))

    def label(self) -> str:
        """``rate_limit(a=…)`` (the values joined by ``/`` when per joint)."""
        value = np.atleast_1d(np.asarray(self.acceleration, dtype=float))
        return "rate_limit(a=" + "/".join(f"{x:g}" for x in value) + ")"
