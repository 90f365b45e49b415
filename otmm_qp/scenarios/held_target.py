"""``held_target``: reachable set-points, each held for a stated time (teleoperation-like)."""

from __future__ import annotations

import math
from numbers import Integral, Real
from typing import ClassVar

import numpy as np
import pinocchio as pin

from otmm_qp.exceptions import ParameterError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.scenarios.generator import Task, TaskGenerator
from otmm_qp.scenarios.search import position_of, random_coordinates, sigma_min_at
from otmm_qp.trajectories.held_targets import HeldTargetsTrajectory
from otmm_qp.validation import Constraints, Interval, check_params


class HeldTargetGenerator(TaskGenerator):
    r"""``targets`` set-points :math:`X_i = f(q_i)`, ``q_i`` uniform in the limits, each held.

    The start :math:`q_0` is uniform in the limits as well; every target is reachable by
    construction (pose tasks use :math:`q_i`'s orientation). The trajectory is a
    :class:`~otmm_qp.trajectories.held_targets.HeldTargetsTrajectory`: the command jumps at
    each switch, which is what a controller meets under teleoperation.

    Descriptors: ``distance`` largest ‖p_i − p_{i−1}‖ [m], ``sigma_min_start``,
    ``sigma_min_target`` (the smallest σ_min over the targets).

    Args:
        targets: Number of set-points ≥ 1.
        hold: Time each is held [s], > 0.
    """

    name = "held_target"

    parameter_constraints: ClassVar[Constraints] = {
        "targets": Interval(Integral, 1, 100),
        "hold": Interval(Real, 0, None, closed="neither", unit="s"),
    }

    def __init__(self, targets: int = 2, hold: float = 1.5) -> None:
        check_params(self, locals())
        if isinstance(targets, bool) or not isinstance(targets, int) or not 1 <= targets <= 100:
            raise ParameterError("targets", f"must be an integer in [1, 100], got {targets!r:.40}")
        if (
            isinstance(hold, bool)
            or not isinstance(hold, int | float)
            or not math.isfinite(hold)
            or not hold > 0.0
        ):
            raise ParameterError("hold", f"must be a finite number > 0 [s], got {hold!r:.40}")
        self.targets = targets
        self.hold = float(hold)

    def generate(self, robot: Robot, seed: int, task_weight: FloatArray | None = None) -> Task:
        """Draw the task of ``seed`` (see the class docstring)."""
        rng = np.random.default_rng(seed)
        q0 = random_coordinates(robot, rng)
        start = np.asarray(robot.forward(robot.configuration(q0)), dtype=float)
        points: list[list[float]] = []
        sigmas: list[float] = []
        previous = position_of(start)
        distance = 0.0
        for _ in range(self.targets):
            qi = random_coordinates(robot, rng)
            value = np.asarray(robot.forward(robot.configuration(qi)), dtype=float)
            point = position_of(value)
            entry = list(point)
            if value.ndim == 2:
                entry += list(pin.rpy.matrixToRpy(value[:3, :3]))
            points.append([float(v) for v in entry])
            sigmas.append(sigma_min_at(robot, qi, task_weight))
            distance = max(distance, float(np.linalg.norm(point - previous)))
            previous = point
        trajectory = HeldTargetsTrajectory(start, points, hold=self.hold)
        descriptors: dict[str, float | int | str] = {
            "distance": distance,
            "sigma_min_start": sigma_min_at(robot, q0, task_weight),
            "sigma_min_target": float(min(sigmas)),
        }
        return Task(q0, trajectory, trajectory.duration, descriptors)
