"""``beyond_reach``: out to a target past the workspace boundary and back."""

from __future__ import annotations

from collections.abc import Sequence
from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.exceptions import ParameterError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.scenarios.generator import Task, TaskGenerator, check_duration, check_range, draw
from otmm_qp.scenarios.reach import true_reach
from otmm_qp.scenarios.search import (
    base_position,
    position_of,
    random_coordinates,
    sigma_min_at,
)
from otmm_qp.trajectories.waypoints import WaypointsTrajectory
from otmm_qp.validation import ArrayOf, Constraints, Interval, check_params


class BeyondReachGenerator(TaskGenerator):
    r"""From a random start ``p_0`` out to ``b + ρ R (p_0 − b)/‖p_0 − b‖`` and back.

    ``b`` is the first joint's origin, ``R`` the robot's true reach computed from its model
    (:func:`~otmm_qp.scenarios.reach.true_reach`: the farthest the frame gets from ``b`` within
    the joint limits, not a sum of link offsets) and ``ρ > 1`` the drawn overshoot, so the
    target is out of reach by ``(ρ − 1)R``. Pose tasks keep the start orientation.

    Descriptors: ``overshoot`` ρ, ``target_distance`` ``ρR`` [m], ``reach`` ``R`` [m],
    ``sigma_min_start``.

    Args:
        overshoot: ``[low, high]`` of ρ (> 1).
        duration: ``[low, high]`` of the out-and-back time [s].
    """

    name = "beyond_reach"

    parameter_constraints: ClassVar[Constraints] = {
        "overshoot": ArrayOf(
            Interval(Real, 1, None, closed="neither"),
            length=2,
            per="end of [low, high], a multiple of the reach",
        ),
        "duration": ArrayOf(
            Interval(Real, 0, None, closed="neither", unit="s"), length=2, per="end of [low, high]"
        ),
    }

    def __init__(
        self, overshoot: Sequence[float] = (1.02, 1.2), duration: Sequence[float] = (2.0, 3.0)
    ) -> None:
        check_params(self, locals())
        self.overshoot = check_range("overshoot", overshoot, lower=1.0)
        if not self.overshoot[0] > 1.0:
            raise ParameterError("overshoot", f"must be > 1, got {list(overshoot)}")
        self.duration = check_duration(duration)

    def generate(self, robot: Robot, seed: int, task_weight: FloatArray | None = None) -> Task:
        """Draw the task of ``seed`` (see the class docstring)."""
        rng = np.random.default_rng(seed)
        q0 = random_coordinates(robot, rng)
        start = robot.forward(robot.configuration(q0))
        p0 = position_of(start)
        base = base_position(robot)
        outward = p0 - base
        if float(np.linalg.norm(outward)) < 1e-9:
            outward = np.eye(p0.size)[0]
        outward /= np.linalg.norm(outward)
        rho = draw(rng, self.overshoot)
        reach = true_reach(robot)
        distance = rho * reach
        target = base + distance * outward
        trajectory = WaypointsTrajectory(
            start, [list(target)], duration=draw(rng, self.duration), return_to_start=True
        )
        descriptors: dict[str, float | int | str] = {
            "overshoot": rho,
            "target_distance": distance,
            "reach": reach,
            "sigma_min_start": sigma_min_at(robot, q0, task_weight),
        }
        return Task(q0, trajectory, trajectory.duration, descriptors)
