"""The certified reach (branch and bound over the joint box) and the per-sample bounds.

Checked against the definitions: dense sampling of the joint box never lands farther than
the certified reach, the reach is never above the sum of offsets, a planar arm with full
joint ranges is bracketed around the sum of its link lengths; the per-sample bound is never
above the merit of any configuration in the speed-reachable box.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp.reference.bound import reach_of
from otmm_qp.reference.chain import chain_of
from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.reference.reach import (
    DegenerateReach,
    certified_reach,
    joint_box,
    model_key,
    search_reach,
)
from otmm_qp.reference.sample_bound import SampleSearch
from otmm_qp.reference.settings import ReferenceSettings
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.robots.robot import Robot
from otmm_qp.trajectories.waypoints import WaypointsTrajectory
from tests.factories import Hold


def sampled_distances(robot: Robot, count: int, seed: int = 0) -> np.ndarray:
    """``‖p(q) − b‖`` [m] at ``count`` configurations drawn in the box, corners included
    (``b`` the first joint's origin)."""
    chain = chain_of(robot)
    lower, upper = joint_box(chain, robot)
    rng = np.random.default_rng(seed)
    q = rng.uniform(lower, upper, (count, chain.size))
    corners = rng.integers(0, 2, (count // 4, chain.size))
    q = np.vstack([q, np.where(corners == 1, upper, lower)])
    p = chain.forward(q)[0][:, : chain.dim]
    base = chain.forward(np.zeros((1, chain.size)))[2][0, 0, : chain.dim]
    return np.linalg.norm(p - base, axis=1)


@pytest.mark.parametrize("name", ["ur5", "panda", "kinova", "xarm7"])
def test_chain_kinematics_match_the_robot(name: str) -> None:
    """The vectorised chain's pose and position Jacobian are the robot's own (Pinocchio),
    continuous joints (Kinova) included; the levers bound every Jacobian column."""
    robot = PinocchioArm(name, task="pose")
    chain = chain_of(robot)
    rng = np.random.default_rng(7)
    lower, upper = joint_box(chain, robot)
    levers = chain.levers(lower, upper)
    for _ in range(10):
        q = np.zeros(robot.nv)
        q[chain.columns] = rng.uniform(lower, upper)
        x, jacobian = robot.kinematics(robot.configuration(q))
        p, rotation, origins, omegas = chain.forward(q[chain.columns][None, :])
        pose = np.asarray(x)
        assert np.allclose(p[0], pose[:3, 3], atol=1e-12)
        assert np.allclose(rotation[0], pose[:3, :3], atol=1e-12)
        columns = chain.jacobian(p, origins, omegas)[0]
        assert np.allclose(columns.T, np.asarray(jacobian)[:3, chain.columns], atol=1e-12)
        assert np.all(np.linalg.norm(columns, axis=1) <= levers + 1e-12)


@pytest.mark.parametrize("name", ["ur5", "panda", "z1"])
def test_no_sampled_configuration_is_past_the_certified_reach(name: str) -> None:
    """UR5, Panda and the Z1 (no shipped config): dense box samples and the robot's own FK."""
    robot = PinocchioArm(name, task="pose")
    certificate = certified_reach(robot)
    assert np.allclose(certificate.base, robot._base, atol=0.0)  # b: the first joint's origin
    distances = sampled_distances(robot, 40_000)
    assert np.max(distances) <= certificate.outer
    assert certificate.found <= certificate.outer <= robot.reach  # below the offset sum
    rng = np.random.default_rng(1)
    lower, upper = robot.position_limits
    for _ in range(20):  # the robot's own kinematics agree with the chain's
        q = rng.uniform(lower, upper)
        position = np.asarray(robot.forward(robot.configuration(q)))[:3, 3]
        assert np.linalg.norm(position - np.asarray(certificate.base)) <= certificate.outer
    # tight: the bracket [found, outer] is narrower than a tenth of the 0.02 m tolerance
    assert certificate.outer - certificate.found < 2e-3


@settings(max_examples=15, deadline=None)
@given(
    lengths=st.lists(st.floats(0.1, 1.0), min_size=2, max_size=4),
    limited=st.booleans(),
    seed=st.integers(0, 2**16),
)
def test_planar_reach_brackets_the_sampled_maximum(
    lengths: list[float], limited: bool, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    limits = None
    if limited:
        low = rng.uniform(-3.0, 0.0, len(lengths))
        limits = np.column_stack([low, low + rng.uniform(0.2, 3.0, len(lengths))]).tolist()
    robot = PlanarArm(lengths, limits=limits)
    certificate = certified_reach(robot)
    assert float(np.max(sampled_distances(robot, 4_000, seed))) <= certificate.outer
    assert certificate.outer <= sum(lengths) * (1 + 1e-8) + 1e-8  # the old bound
    if not limited:  # full ranges: the true reach is the stretched arm, Σ l
        assert certificate.found <= sum(lengths) <= certificate.outer
        assert certificate.outer - sum(lengths) <= 1e-5 * sum(lengths)


def test_cached_per_model_and_stored(tmp_path: Path) -> None:
    robot = PinocchioArm("ur5", task="pose")
    first = certified_reach(robot, tmp_path)
    stored = list(tmp_path.glob("reach-*.json"))
    assert [p.name for p in stored] == [f"reach-{first.key}.json"]
    assert certified_reach(PinocchioArm("ur5", task="pose")) is first  # same model: cached
    limited = PinocchioArm(
        "ur5", task="pose", position_limits=[[-1.0, 1.0]] * 6
    )  # other limits: another key, a smaller reach
    other = certified_reach(limited, tmp_path)
    assert other.key != first.key and other.outer <= first.outer + 1e-12
    assert len(list(tmp_path.glob("reach-*.json"))) == 2
    chain = chain_of(robot)
    assert model_key(chain, *joint_box(chain, robot)) == first.key


URDF = """<?xml version="1.0"?>
<robot name="slider">
  <link name="base"/><link name="arm"/><link name="tip"/><link name="tool"/>
  <joint name="turn" type="revolute"><parent link="base"/><child link="arm"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" velocity="1" effort="1"/></joint>
  <joint name="slide" type="prismatic"><parent link="arm"/><child link="tip"/>
    <origin xyz="0.2 0 0"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="0.3" velocity="1" effort="1"/></joint>
  <joint name="fixed_tool" type="fixed"><parent link="tip"/><child link="tool"/>
    <origin xyz="0.05 0 0"/></joint>
</robot>
"""


def test_prismatic_chain_and_degenerate_boxes(tmp_path: Path) -> None:
    urdf = tmp_path / "slider.urdf"
    urdf.write_text(URDF)
    robot = PinocchioArm(urdf=str(urdf), frame="tool", task="position")
    certificate = certified_reach(robot)
    assert certificate.found <= 0.55 <= certificate.outer <= 0.55 + 1e-5  # 0.2 + 0.3 + 0.05
    # an unbounded prismatic joint: no certificate, and the bound falls back to none
    unbounded = PinocchioArm(
        urdf=str(urdf), frame="tool", task="position", position_limits=[[-3, 3], [0, math.inf]]
    )
    with pytest.raises(DegenerateReach, match="prismatic"):
        certified_reach(unbounded)
    reach = reach_of(unbounded)
    assert reach is not None and reach.outer == math.inf
    # a frame on the base: nothing moves it, the reach is its fixed distance (0)
    on_base = PinocchioArm(urdf=str(urdf), frame="base", task="position")
    assert certified_reach(on_base).outer <= 1e-8


def test_continuous_joints_are_circles() -> None:
    """The Kinova's continuous joints (±inf limits) are searched over [−π, π]."""
    robot = PinocchioArm("kinova", task="pose")
    chain = chain_of(robot)
    lower, upper = joint_box(chain, robot)
    assert np.all(np.isfinite(lower)) and np.all(upper - lower <= 2 * math.pi + 1e-12)
    certificate = search_reach(chain, lower, upper, max_boxes=2_000)  # stopped early: valid
    assert not certificate.converged
    assert float(np.max(sampled_distances(robot, 8_000))) <= certificate.outer
    assert certificate.outer <= robot.reach * (1 + 1e-8) + 1e-8


def _problem(robot: Robot, target: np.ndarray, q0: np.ndarray, duration: float) -> TrackingProblem:
    x0 = robot.forward(robot.configuration(q0))
    trajectory = WaypointsTrajectory(x0, [target], duration=duration)
    settings_ = ReferenceSettings(position_tolerance=0.02, orientation_tolerance=0.1)
    return TrackingProblem(robot, trajectory, q0, 0.02, duration, settings_)


@settings(max_examples=12, deadline=None)
@given(
    lengths=st.lists(st.floats(0.2, 0.8), min_size=2, max_size=3),
    seed=st.integers(0, 2**16),
    sample=st.integers(1, 24),
)
def test_sample_bound_is_below_every_configuration_of_the_box(
    lengths: list[float], seed: int, sample: int
) -> None:
    rng = np.random.default_rng(seed)
    robot = PlanarArm(lengths, velocity_limits=[2.0] * len(lengths))
    q0 = rng.uniform(-2.0, 2.0, len(lengths))
    target = rng.uniform(-1.2, 1.2, 2) * sum(lengths)
    problem = _problem(robot, target, q0, 0.5)
    search = SampleSearch(problem)
    result = search.bound(sample, 4_000)
    box = np.abs(np.arange(-1.0, 1.0001, 0.25)) * sample * problem.step[0]
    configurations = q0 + rng.uniform(-1.0, 1.0, (2_000, len(lengths))) * sample * problem.step
    configurations = np.vstack(
        [configurations, q0 + box[:, None] * np.sign(rng.normal(size=len(lengths)))]
    )
    merits = problem.merits(
        np.array(
            [robot.task_error(problem.targets[sample], robot.forward(q)) for q in configurations]
        )
    )
    assert result.merit <= float(np.min(merits))
    assert result.merit <= result.found


def test_sample_bound_on_a_ur5_pose_task_is_below_sampled_merits() -> None:
    robot = PinocchioArm("ur5", task="pose")
    rng = np.random.default_rng(3)
    q0 = rng.uniform(-1.5, 1.5, 6)
    x0 = np.asarray(robot.forward(robot.configuration(q0)))
    target = x0.copy()
    target[:3, 3] *= 1.3  # a jump at t = 0, held
    settings_ = ReferenceSettings(position_tolerance=0.02, orientation_tolerance=0.1)
    problem = TrackingProblem(robot, Hold(target), q0, 0.02, 0.6, settings_)
    sample = 4  # a box of ±4 steps: small enough to certify in a few thousand boxes
    result = SampleSearch(problem).bound(sample, 20_000)
    step = sample * problem.step
    configurations = np.clip(
        q0 + rng.uniform(-1.0, 1.0, (500, 6)) * step, problem.lower, problem.upper
    )
    errors = np.array(
        [robot.task_error(problem.targets[sample], robot.forward(q)) for q in configurations]
    )
    assert result.merit <= float(np.min(problem.merits(errors)))
    assert result.merit > 1.0  # the target jumped away: certified out of this box
