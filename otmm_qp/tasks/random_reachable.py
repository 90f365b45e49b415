"""``random_reachable``: reach the FK of a random configuration (a non-singular baseline)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.tasks.generator import Task, TaskGenerator, check_duration, draw
from otmm_qp.tasks.search import position_of, random_coordinates, sigma_min_at
from otmm_qp.trajectories.waypoints import WaypointsTrajectory


class RandomReachableGenerator(TaskGenerator):
    r"""From ``f(q_0)`` to ``f(q_1)`` along a task-space line, ``q_0, q_1`` uniform in the limits.

    The protocol of the IK benchmarks' success rates (targets are reachable by
    construction). Pose tasks slerp to ``q_1``'s orientation.

    Descriptors: ``distance`` ‖p_1 − p_0‖ [m], ``sigma_min_start``, ``sigma_min_target``.

    Args:
        duration: ``[low, high]`` of the motion time [s].
    """

    name = "random_reachable"

    def __init__(self, duration: Sequence[float] = (2.0, 3.0)) -> None:
        self.duration = check_duration(duration)

    def generate(self, robot: Robot, seed: int, task_weight: FloatArray | None = None) -> Task:
        """Draw the task of ``seed`` (see the class docstring)."""
        rng = np.random.default_rng(seed)
        q0 = random_coordinates(robot, rng)
        q1 = random_coordinates(robot, rng)
        start = robot.forward(robot.configuration(q0))
        target = np.asarray(robot.forward(robot.configuration(q1)), dtype=float)
        p1 = position_of(target)
        waypoint = list(p1)
        if target.ndim == 2:
            waypoint += list(pin.rpy.matrixToRpy(target[:3, :3]))
        trajectory = WaypointsTrajectory(start, [waypoint], duration=draw(rng, self.duration))
        descriptors: dict[str, float | int | str] = {
            "distance": float(np.linalg.norm(p1 - position_of(start))),
            "sigma_min_start": sigma_min_at(robot, q0, task_weight),
            "sigma_min_target": sigma_min_at(robot, q1, task_weight),
        }
        return Task(q0, trajectory, trajectory.duration, descriptors)
