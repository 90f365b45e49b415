r"""The two-rate scheme: the preview QP every ``N`` control steps, the one-step QP in between.

At the preview steps (``k mod N = 0``) the :class:`~.backend.PreviewBackend` QP is solved (its
nominal: the last plan advanced by ``N`` steps, :math:`\bar v = M^N v`) and its first velocity
executed; at the ``N − 1`` steps in between the project's one-step ``qp`` backend (same limits)
tracks the plan's knots: with the plan's displacement :math:`P(\tau)` from the joint
coordinates :math:`\theta_a` of the last preview step at :math:`t_a`, the command of step
``t`` is the Newton step to the plan's next point,

.. math:: \dot x_w = W\,e\big(x(\theta_a + P(t + dt - t_a)),\ x(\theta)\big) / dt,

one forward kinematics call and one small QP (usually its closed-form fast path). The
expensive QP thus runs at ``1/(N·dt)`` Hz (50 Hz for ``N = 10`` at dt = 2 ms).
"""

from __future__ import annotations

from collections.abc import Sequence
from numbers import Integral, Real
from typing import ClassVar

import numpy as np

from otmm_qp.backends.backend import BackendOutput
from otmm_qp.limits import LimitSpec
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.validation import Constraints, Interval, check_params

from ..qp.backend import QpBackend
from .backend import InfeasiblePolicy, PreviewBackend

__all__ = ["TwoRatePreviewBackend"]


class TwoRatePreviewBackend(PreviewBackend):
    """``preview_two_rate``: :class:`PreviewBackend` every ``every`` steps, ``qp`` in between.

    Args:
        every: ``N``, control steps per preview QP, an integer ≥ 1 (1: the preview backend).
        tracker_regularization: μ of the tracking ``qp`` backend (> 0).
        limits: The limits of both QPs (None: velocity and position, gain 0.5).
        horizon, knots, fine_steps, coarse_step, regularization, smoothness, jump,
        trust_region, solver, infeasible_policy, fast_path: As :class:`PreviewBackend`.
    """

    name = "preview_two_rate"
    parameter_constraints: ClassVar[Constraints] = {
        **PreviewBackend.parameter_constraints,
        "every": Interval(Integral, 1, None, closed="left"),
        "tracker_regularization": Interval(Real, 0, None, closed="neither"),
    }

    def __init__(
        self,
        every: int = 10,
        tracker_regularization: float = 1e-4,
        horizon: float = 1.0,
        knots: int = 16,
        fine_steps: int = 4,
        coarse_step: float | None = None,
        regularization: float = 1e-4,
        smoothness: float = 0.001,
        jump: float = 0.0,
        trust_region: float = 1e-3,
        solver: str = "daqp",
        limits: Sequence[LimitSpec] | None = None,
        infeasible_policy: InfeasiblePolicy = "raise",
        fast_path: bool = True,
    ) -> None:
        check_params(self, locals())
        super().__init__(
            horizon, knots, fine_steps, coarse_step, regularization, smoothness, jump,
            trust_region, solver, limits, infeasible_policy, fast_path,
        )  # fmt: skip
        self.every = int(every)
        self.tracker = QpBackend(
            regularization=float(tracker_regularization),
            solver=solver,
            limits=list(self.limits.all),
            infeasible_policy=infeasible_policy,
        )

    def bind(self, robot: Robot, dt: float) -> None:
        """Bind both QPs; the preview's nominal advances ``N`` steps per solve."""
        super().bind(robot, dt)
        self._shift = np.linalg.matrix_power(self._shift, self.every)
        self.tracker.bind(robot, dt)
        self._anchor: tuple[float, FloatArray, FloatArray, FloatArray] | None = None

    def reset(self) -> None:
        """Forget both QPs' warm starts and the plan."""
        super().reset()
        if hasattr(self.tracker, "robot"):
            self.tracker.reset()
        self._anchor = None

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """The preview QP at ``k mod N = 0`` (or with no plan yet), else ``qp`` on the plan."""
        if self._k % self.every == 0 or self._anchor is None:
            t = self._k * self.dt
            output = super().solve(state, xdot, qdot_prev)
            theta = state.q if self.robot.nq == self.robot.nv else self.robot.joint_coordinates(
                state.q
            )  # fmt: skip
            knots = np.concatenate([[0.0], self.grid.taus])
            path = np.vstack([np.zeros(self.robot.nv), np.cumsum(
                self.grid.steps[:, None] * self._plan, axis=0
            )])  # fmt: skip
            self._anchor = (t, np.array(theta), knots, path)
            return output
        t = self._k * self.dt
        self._k += 1
        start, theta_a, knots, path = self._anchor
        ahead = min(t + self.dt - start, float(knots[-1]))
        point = np.array([np.interp(ahead, knots, column) for column in path.T])
        robot = self.robot
        target, _ = robot.kinematics(robot.configuration(theta_a + point))
        command = state.weight * robot.task_error(target, state.x) / self.dt
        return self.tracker.solve(state, command, qdot_prev)
