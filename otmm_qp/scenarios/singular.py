"""Finding singular configurations within a budget: σ_min descent, then bounded minimisation."""

from __future__ import annotations

import numpy as np

from otmm_qp.exceptions import ParameterError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.scenarios.generator import TaskGenerationError
from otmm_qp.scenarios.search import (
    descend_sigma_min,
    minimise_sigma_min,
    random_coordinates,
    sampling_bounds,
)


class SingularSearch:
    """Budget of the search for a configuration with σ_min below ``tolerance``.

    Args:
        tolerance: σ_min threshold [task units], > 0.
        restarts: Random starts, ≥ 1.
        iterations: Descent iterations per start, ≥ 1.
    """

    def __init__(self, tolerance: float, restarts: int, iterations: int) -> None:
        if not tolerance > 0.0:
            raise ParameterError("sigma_tolerance", f"must be > 0, got {tolerance}")
        if int(restarts) < 1:
            raise ParameterError("restarts", f"must be >= 1, got {restarts}")
        if int(iterations) < 1:
            raise ParameterError("iterations", f"must be >= 1, got {iterations}")
        self.tolerance = float(tolerance)
        self.restarts = int(restarts)
        self.iterations = int(iterations)

    def find(
        self, robot: Robot, rng: np.random.Generator, generator: str, weight: FloatArray | None
    ) -> FloatArray:
        """Joint coordinates ``(nv,)`` with σ_min < tolerance.

        Newton steps on σ_min = 0 from each random start first (:func:`descend_sigma_min`);
        when none converges (a redundant arm's position task, singular only against its joint
        limits), σ_min is minimised inside the limits (:func:`minimise_sigma_min`) from the
        mid-range pose and fresh random starts, the same budget.

        Raises:
            TaskGenerationError: Neither converged within the budget (names the robot).
        """
        for _ in range(self.restarts):
            found = descend_sigma_min(
                robot, random_coordinates(robot, rng), self.tolerance, self.iterations, weight
            )
            if found is not None:
                return found
        lower, upper = sampling_bounds(robot)
        starts = [0.5 * (lower + upper)]
        for start in starts + [random_coordinates(robot, rng) for _ in range(self.restarts - 1)]:
            found = minimise_sigma_min(robot, start, self.tolerance, self.iterations, weight)
            if found is not None:
                return found
        raise TaskGenerationError(
            generator,
            robot.name,
            f"no singular configuration (sigma_min < {self.tolerance:g}) found within "
            f"{self.restarts} starts x {self.iterations} iterations",
        )
