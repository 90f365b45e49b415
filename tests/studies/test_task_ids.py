"""Tasks that are what their names say: true reach, reachable baselines, one seed per entry."""

from __future__ import annotations

import numpy as np
import pytest

from otmm_qp import registry
from otmm_qp.exceptions import ConfigError
from otmm_qp.reference import ReferenceSettings, solve_reference
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.robots.robot import Robot
from otmm_qp.scenarios.reach import true_reach
from otmm_qp.scenarios.search import base_position, position_of, random_coordinates
from otmm_qp.studies.spec import parse_study, plan_study
from otmm_qp.studies.task_ids import entry_label, seed_name, task_id


@pytest.fixture(scope="module", params=["ur5", "panda"])
def arm(request: pytest.FixtureRequest) -> Robot:
    robot: Robot = registry.create(
        registry.ROBOTS, "pinocchio", {"name": request.param, "task": "pose"}, "r"
    )
    return robot


def test_planar_true_reach_is_the_stretched_arm() -> None:
    assert true_reach(PlanarArm([1.0, 0.8, 0.5])) == pytest.approx(2.3, abs=1e-9)
    limited = PlanarArm([1.0, 0.8], limits=[[-3.0, 3.0], [0.8, 2.5]])
    assert true_reach(limited) == pytest.approx(np.sqrt(1.64 + 1.6 * np.cos(0.8)), abs=1e-7)


def test_arm_true_reach_is_about_0_95_m_and_bounds_every_sample(arm: Robot) -> None:
    """UR5 and Panda reach ≈ 0.95 m (their link-offset sums are 1.24 / 1.09 m)."""
    reach = true_reach(arm)
    assert 0.93 < reach < 0.97
    # The values README.md and docs/studies.md publish.
    assert f"{reach:.3f}" == {"ur5": "0.950", "panda": "0.947"}[arm.name]
    assert reach < arm.reach  # tighter than the sum of link offsets
    rng = np.random.default_rng(5)
    base = base_position(arm)
    for _ in range(500):
        q = random_coordinates(arm, rng, 0.0)
        assert float(np.linalg.norm(position_of(arm.forward(arm.configuration(q))) - base)) <= (
            reach + 1e-9
        )


@pytest.mark.parametrize("seed", [11, 12])
def test_random_reachable_is_a_joint_path_within_every_limit_and_certified(
    arm: Robot, seed: int
) -> None:
    generator = registry.create(
        registry.TASK_GENERATORS, "random_reachable", {"duration": [1.5, 2.5]}, "g"
    )
    task = generator.generate(arm, seed)
    lower, upper = arm.position_limits
    times = np.arange(0.0, task.duration + 1e-9, 0.01)
    joints = np.array([task.trajectory.joint_sample(float(t))[0] for t in times])  # type: ignore[attr-defined]
    speeds = np.array([task.trajectory.joint_sample(float(t))[1] for t in times])  # type: ignore[attr-defined]
    assert np.all(joints >= lower) and np.all(joints <= upper)
    assert np.all(np.abs(speeds) <= np.minimum(1.5, 0.8 * arm.velocity_limits) + 1e-9)
    assert float(task.descriptors["path_speed"]) <= 1.5 + 1e-12
    settings = ReferenceSettings(0.02, 0.1, speed_limit=3.0)
    result, _ = solve_reference(arm, task.trajectory, task.q0, 0.02, task.duration + 0.5, settings)
    assert result.status == "achievable" and result.max_error < 1e-3


def test_random_reachable_bad_parameters_name_the_field() -> None:
    for params, field in (({"joint_speed": 0.0}, "joint_speed"), ({"speed_fraction": 2}, "speed")):
        with pytest.raises(ConfigError, match=field):
            registry.create(registry.TASK_GENERATORS, "random_reachable", params, "generators.0")


def _study(generators: list[dict]) -> dict:
    return {
        "name": "names",
        "seed": 3,
        "dt": 0.05,
        "reference": {"enabled": False},
        "robots": [{"name": "planar2", "robot": {"type": "planar", "link_lengths": [1.0, 0.8]}}],
        "generators": generators,
        "controllers": [{"name": "pinv", "backend": {"type": "pinv"}}],
    }


def test_two_entries_of_one_type_get_different_seeds_and_labels() -> None:
    config = parse_study(
        _study(
            [
                {"type": "near_singular", "count": 2, "distance": [0.0, 0.02]},
                {"type": "near_singular", "count": 2, "distance": [0.05, 0.1]},
                {"type": "beyond_reach", "count": 1, "name": "far"},
            ]
        )
    )
    assert [entry_label(config, j) for j in range(3)] == [
        "near_singular#0",
        "near_singular#1",
        "far",
    ]
    # The first entry of a type keeps the type's seeds (studies with one entry per type keep
    # their tasks); later ones get their own.
    assert [seed_name(config, j) for j in range(3)] == ["near_singular", "near_singular#1", "far"]
    assert task_id(config, 0, 1, 4) == "planar2/near_singular#1/4"
    plan = plan_study(config, "s")
    seeds = {(e.generator, e.task_index): e.seed for e in plan.episodes}
    assert len(set(seeds.values())) == len(seeds) == 5
    assert len({e.key for e in plan.episodes}) == len(plan.episodes)


@pytest.mark.parametrize(
    "generators",
    [
        [
            {"type": "boundary", "count": 1, "name": "a"},
            {"type": "joint_path", "count": 1, "name": "a"},
        ],
        [{"type": "boundary", "count": 1}, {"type": "joint_path", "count": 1, "name": "boundary"}],
        [{"type": "boundary", "count": 1}, {"type": "boundary", "count": 1, "name": "boundary#0"}],
    ],
)
def test_colliding_entries_are_refused_in_one_line(generators: list[dict]) -> None:
    with pytest.raises(ConfigError, match=r"generators\.1\.name") as error:
        plan_study(parse_study(_study(generators)), "s.yaml")
    assert "\n" not in str(error.value) and "distinct name" in str(error.value)
