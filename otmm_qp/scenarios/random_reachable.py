"""``random_reachable``: follow the FK of a joint path inside the limits (a reachable baseline)."""

from __future__ import annotations

from collections.abc import Sequence
from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.exceptions import ParameterError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.scenarios.generator import Task, TaskGenerator, check_duration, draw
from otmm_qp.scenarios.search import position_of, random_coordinates, sigma_min_at
from otmm_qp.trajectories.waypoints import JointWaypointsTrajectory
from otmm_qp.validation import ArrayOf, Constraints, Interval, check_params

#: Peak speed of the quintic law over its mean: ``max ṡ = 15/8``.
QUINTIC_PEAK = 1.875


class RandomReachableGenerator(TaskGenerator):
    r"""From ``q_0`` toward ``q_1`` (uniform in the limits) along a joint-space line; its FK.

    .. math:: q(t) = q_0 + s(t)\,c\,(q_1 - q_0),\qquad x_d(t) = f(q(t)),\qquad
              c = \min\Big(1, \frac{\dot q_{path}\,T}{1.875\,\|q_1 - q_0\|_\infty}\Big)

    with the quintic law ``s``, so the joint path stays in the (convex) limit box and its
    peak joint speed is at most ``q̇_path = min(joint_speed, speed_fraction · v_max,i)``.
    The task is reachable along the *whole* path within the position and speed limits by
    construction: the joint path itself tracks it with zero error. (The earlier version
    joined ``f(q_0)`` and ``f(q_1)`` by a task-space line, which often leaves the workspace
    or needs more than the speed bound.)

    Descriptors: ``distance`` ‖p_1 − p_0‖ [m], ``joint_distance`` ‖Δq‖∞ [rad],
    ``path_speed`` peak joint speed of the path [rad/s], ``sigma_min_start``,
    ``sigma_min_target``.

    Args:
        duration: ``[low, high]`` of the motion time [s].
        joint_speed: Peak joint speed of the path [rad/s], > 0.
        speed_fraction: Largest fraction of each joint's speed limit the path uses, in (0, 1].
    """

    name = "random_reachable"

    parameter_constraints: ClassVar[Constraints] = {
        "duration": ArrayOf(
            Interval(Real, 0, None, closed="neither", unit="s"), length=2, per="end of [low, high]"
        ),
        "joint_speed": Interval(Real, 0, None, closed="neither", unit="rad/s"),
        "speed_fraction": Interval(Real, 0, 1, closed="right"),
    }

    def __init__(
        self,
        duration: Sequence[float] = (2.0, 3.0),
        joint_speed: float = 1.5,
        speed_fraction: float = 0.8,
    ) -> None:
        check_params(self, locals())
        self.duration = check_duration(duration)
        if not (isinstance(joint_speed, int | float) and 0.0 < joint_speed < float("inf")):
            raise ParameterError("joint_speed", f"must be a finite number > 0, got {joint_speed}")
        if not (isinstance(speed_fraction, int | float) and 0.0 < speed_fraction <= 1.0):
            raise ParameterError("speed_fraction", f"must lie in (0, 1], got {speed_fraction}")
        self.joint_speed = float(joint_speed)
        self.speed_fraction = float(speed_fraction)

    def generate(self, robot: Robot, seed: int, task_weight: FloatArray | None = None) -> Task:
        """Draw the task of ``seed`` (see the class docstring)."""
        rng = np.random.default_rng(seed)
        q0 = random_coordinates(robot, rng)
        q1 = random_coordinates(robot, rng)
        duration = draw(rng, self.duration)
        limits = np.asarray(robot.velocity_limits, dtype=float)
        speed = np.minimum(self.joint_speed, self.speed_fraction * limits)  # (nv,)
        delta = q1 - q0
        # Largest c with 1.875 c |Δq_i| / T ≤ speed_i for every joint.
        ratio = np.max(QUINTIC_PEAK * np.abs(delta) / (speed * duration))
        q1 = q0 + delta / max(1.0, float(ratio))
        start = robot.forward(robot.configuration(q0))
        trajectory = JointWaypointsTrajectory(start, robot, [list(q0), list(q1)], duration=duration)
        target = robot.forward(robot.configuration(q1))
        descriptors: dict[str, float | int | str] = {
            "distance": float(np.linalg.norm(position_of(target) - position_of(start))),
            "joint_distance": float(np.max(np.abs(q1 - q0))),
            "path_speed": float(np.max(QUINTIC_PEAK * np.abs(q1 - q0) / duration)),
            "sigma_min_start": sigma_min_at(robot, q0, task_weight),
            "sigma_min_target": sigma_min_at(robot, q1, task_weight),
        }
        return Task(q0, trajectory, trajectory.duration, descriptors)
