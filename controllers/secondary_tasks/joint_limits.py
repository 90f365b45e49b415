r"""Joint-limit avoidance task: descend the limit-distance cost of Liégeois (1977)."""

from __future__ import annotations

from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.validation import Constraints, Interval, check_params

from .secondary_task import SecondaryTask


def limit_distance_gradient(theta: FloatArray, lower: FloatArray, upper: FloatArray) -> FloatArray:
    r"""Gradient of Liégeois' limit-distance cost H(θ), shape ``(nv,)`` [1/rad].

    .. math:: H(\theta) = \frac{1}{2n}\sum_i\Big(\frac{\theta_i - \bar\theta_i}
              {\theta_{max,i} - \theta_{min,i}}\Big)^2

    .. math:: \partial H/\partial\theta_i = \frac{\theta_i - \bar\theta_i}
              {n\,(\theta_{max,i} - \theta_{min,i})^2},\quad
              \bar\theta_i = \tfrac12(\theta_{min,i} + \theta_{max,i})

    Zero for joints with an infinite (or empty) limit interval.
    """
    span = upper - lower
    usable = np.isfinite(span) & (span > 0.0)
    safe_span = np.where(usable, span, 1.0)
    middle = np.where(
        usable, 0.5 * (np.where(usable, lower, 0.0) + np.where(usable, upper, 0.0)), 0.0
    )
    n = max(int(np.count_nonzero(usable)), 1)
    return np.where(usable, (theta - middle) / (n * safe_span**2), 0.0)


class JointLimitTask(SecondaryTask):
    r"""Gradient descent on the limit-distance cost: :math:`\dot q_2 = -k\,\nabla H(\theta)`.

    See :func:`limit_distance_gradient`; the motion pulls every limited joint toward the
    middle of its range, harder for narrow ranges.

    Args:
        gain: k ≥ 0 [rad²/s].
    """

    name = "joint_limits"
    parameter_constraints: ClassVar[Constraints] = {
        "gain": Interval(Real, 0, None, closed="left"),
    }

    def __init__(self, gain: float = 1.0) -> None:
        check_params(self, locals())
        self.gain = float(gain)

    def joint_velocity(self, robot: Robot, state: KinematicState) -> FloatArray:
        """``−k ∇H(θ)`` [rad/s], shape ``(nv,)``."""
        lower, upper = (np.asarray(v, dtype=float) for v in robot.position_limits)
        theta = robot.joint_coordinates(state.q)
        return np.asarray(-self.gain * limit_distance_gradient(theta, lower, upper), dtype=float)
