"""``boundary``: an arc along the outer workspace boundary."""

from __future__ import annotations

import math
from collections.abc import Sequence
from numbers import Integral, Real
from typing import ClassVar, Literal

import numpy as np

from otmm_qp.exceptions import ParameterError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.scenarios.generator import (
    Task,
    TaskGenerationError,
    TaskGenerator,
    check_duration,
    check_range,
    draw,
)
from otmm_qp.scenarios.search import (
    base_position,
    position_of,
    random_coordinates,
    sigma_min_at,
    solve_ik,
    with_position,
)
from otmm_qp.trajectories.circle import CircleTrajectory
from otmm_qp.trajectories.pose import PoseCircleTrajectory
from otmm_qp.trajectories.trajectory import Trajectory
from otmm_qp.validation import ArrayOf, Constraints, Interval, check_params

#: Random configurations sampled to estimate the outer radius (deterministic seed).
RADIUS_SAMPLES = 400


def outer_radius(robot: Robot) -> float:
    """Largest sampled distance of the end effector from the first joint's origin [m]."""
    rng = np.random.default_rng(12345)
    base = base_position(robot)
    best = 0.0
    for _ in range(RADIUS_SAMPLES):
        q = random_coordinates(robot, rng, 0.0)
        best = max(
            best, float(np.linalg.norm(position_of(robot.forward(robot.configuration(q))) - base))
        )
    return best


class BoundaryGenerator(TaskGenerator):
    r"""Arc of a horizontal circle about the base axis at ``ρ`` times the outer radius.

    The sphere of radius ``ρ R_out`` about the first joint ``b`` (``R_out`` estimated as the
    largest distance over deterministic random configurations) is cut at a drawn elevation
    ``β``; the task sweeps an arc of angle ``θ`` of that circle with a quintic law (planar
    arms: the circle of radius ``ρ R_out`` itself). Pose tasks hold the start orientation.
    The start configuration is found by position IK from random configurations.

    Descriptors: ``radius_fraction`` ρ, ``elevation`` β [rad], ``sweep`` θ [rad],
    ``sigma_min_start``.

    Args:
        radius_fraction: ``[low, high]`` of ρ (≤ 1).
        elevation: ``[low, high]`` of β [rad] (3-D arms).
        sweep: ``[low, high]`` of θ [rad].
        duration: ``[low, high]`` of the motion time [s].
        attempts: IK attempts (random initial configurations) before giving up.
    """

    name = "boundary"

    parameter_constraints: ClassVar[Constraints] = {
        "radius_fraction": ArrayOf(
            Interval(Real, 0, 1, closed="right"),
            length=2,
            per="end of [low, high], a fraction of the reach",
        ),
        "elevation": ArrayOf(
            Interval(Real, -math.pi / 2, None, unit="rad"), length=2, per="end of [low, high]"
        ),
        "sweep": ArrayOf(
            Interval(Real, 0, None, closed="neither", unit="rad"),
            length=2,
            per="end of [low, high]",
        ),
        "duration": ArrayOf(
            Interval(Real, 0, None, closed="neither", unit="s"), length=2, per="end of [low, high]"
        ),
        "attempts": Interval(Integral, 1, None),
    }

    def __init__(
        self,
        radius_fraction: Sequence[float] = (0.85, 0.97),
        elevation: Sequence[float] = (-0.3, 0.8),
        sweep: Sequence[float] = (0.8, 2.0),
        duration: Sequence[float] = (2.0, 3.0),
        attempts: int = 20,
    ) -> None:
        check_params(self, locals())
        self.radius_fraction = check_range("radius_fraction", radius_fraction)
        if not (0.0 < self.radius_fraction[0] and self.radius_fraction[1] <= 1.0):
            raise ParameterError("radius_fraction", f"must lie in (0, 1], got {radius_fraction}")
        self.elevation = check_range("elevation", elevation, lower=-math.pi / 2)
        self.sweep = check_range("sweep", sweep)
        if not self.sweep[0] > 0.0:
            raise ParameterError("sweep", f"must be > 0 [rad], got {list(sweep)}")
        self.duration = check_duration(duration)
        if int(attempts) < 1:
            raise ParameterError("attempts", f"must be >= 1, got {attempts}")
        self.attempts = int(attempts)
        self._radii: dict[str, float] = {}

    def generate(self, robot: Robot, seed: int, task_weight: FloatArray | None = None) -> Task:
        """Draw the task of ``seed`` (see the class docstring)."""
        rng = np.random.default_rng(seed)
        if robot.name not in self._radii:
            self._radii[robot.name] = outer_radius(robot)
        r_out = self._radii[robot.name]
        base = base_position(robot)
        for _ in range(self.attempts):
            rho = draw(rng, self.radius_fraction)
            beta = draw(rng, self.elevation) if base.size == 3 else 0.0
            theta = draw(rng, self.sweep)
            phi0 = float(rng.uniform(-math.pi, math.pi))
            direction: Literal["clockwise", "counterclockwise"] = (
                "counterclockwise" if rng.random() < 0.5 else "clockwise"
            )
            duration = draw(rng, self.duration)
            radius = rho * r_out * math.cos(beta)
            centre = base.copy()
            if base.size == 3:
                centre[2] += rho * r_out * math.sin(beta)
            offset = np.zeros(base.size)
            offset[0], offset[1] = radius * math.cos(phi0), radius * math.sin(phi0)
            q_init = random_coordinates(robot, rng)
            x_init = robot.forward(robot.configuration(q_init))
            q0 = solve_ik(robot, q_init, with_position(x_init, centre + offset), position_only=True)
            if q0 is None or not radius > 0.0:
                continue
            start = robot.forward(robot.configuration(q0))
            period = 2.0 * math.pi * duration / theta
            turns = theta / (2.0 * math.pi)
            trajectory: Trajectory
            if np.asarray(start).ndim == 2:
                trajectory = PoseCircleTrajectory(
                    start, list(centre), radius, period, direction, turns=turns
                )
            else:
                trajectory = CircleTrajectory(
                    start, list(centre), radius, period, direction, turns=turns, profile="quintic"
                )
            descriptors: dict[str, float | int | str] = {
                "radius_fraction": rho,
                "elevation": beta,
                "sweep": theta,
                "sigma_min_start": sigma_min_at(robot, q0, task_weight),
            }
            return Task(q0, trajectory, trajectory.duration, descriptors)
        raise TaskGenerationError(
            self.name,
            robot.name,
            f"no start on the boundary circle within {self.attempts} attempts",
        )
