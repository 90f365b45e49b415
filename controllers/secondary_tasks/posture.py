r"""Posture task: pull the joints toward a nominal configuration."""

from __future__ import annotations

import math
from collections.abc import Sequence
from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.exceptions import DimensionError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.validation import ArrayOf, Constraints, Interval, check_params

from .secondary_task import SecondaryTask


class PostureTask(SecondaryTask):
    r"""Proportional pull to a nominal posture, each joint's speed capped.

    .. math::
        \dot q_{2,i} = \mathrm{clip}\big(k\,(\theta^{nom}_i - \theta_i),\ -v_{max},\ v_{max}\big)

    (the null-space motion the J-PARSE authors command toward their home posture, with their
    cap ``null_space_angle_rate``).

    Args:
        gain: k ≥ 0 [1/s].
        q_nominal: θ^nom [rad or m], shape ``(nv,)``; ``None``: the middle of each finite
            position-limit interval, 0 for unlimited joints.
        max_speed: v_max > 0 [rad/s] (``None``: no cap).
    """

    name = "posture"
    parameter_constraints: ClassVar[Constraints] = {
        "gain": Interval(Real, 0, None, closed="left"),
        "q_nominal": [ArrayOf(Interval(Real, None, None), per="joint"), None],
        "max_speed": [Interval(Real, 0, None, closed="neither", unit="rad/s"), None],
    }

    def __init__(
        self,
        gain: float = 1.0,
        q_nominal: Sequence[float] | None = None,
        max_speed: float | None = None,
    ) -> None:
        check_params(self, locals())
        self.gain = float(gain)
        self.max_speed = math.inf if max_speed is None else float(max_speed)
        self.q_nominal: FloatArray | None = (
            None if q_nominal is None else np.asarray(q_nominal, dtype=float)
        )
        self._nominal = self.q_nominal

    def bind(self, robot: Robot) -> None:
        """Check ``q_nominal`` against ``nv``, or derive it from the limits."""
        if self.q_nominal is not None:
            if self.q_nominal.shape != (robot.nv,):
                raise DimensionError("secondary.q_nominal", (robot.nv,), self.q_nominal.shape)
            self._nominal = self.q_nominal
            return
        lower, upper = (np.asarray(v, dtype=float) for v in robot.position_limits)
        finite = np.isfinite(lower) & np.isfinite(upper)
        self._nominal = np.where(
            finite, 0.5 * (np.where(finite, lower, 0.0) + np.where(finite, upper, 0.0)), 0.0
        )

    def joint_velocity(self, robot: Robot, state: KinematicState) -> FloatArray:
        """``clip(k (θ_nom − θ), ±v_max)`` [rad/s], shape ``(nv,)``."""
        assert self._nominal is not None  # noqa: S101 - set by bind
        theta = robot.joint_coordinates(state.q)
        return np.clip(self.gain * (self._nominal - theta), -self.max_speed, self.max_speed)
