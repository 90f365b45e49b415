"""The wrist bound (:mod:`otmm_qp.reference.wrist`) checked against its definition.

The carried points are where the robot's own kinematics put the joint origins (on their
circles in the frame's coordinates); dense sampling of the joint box never brings them past
their certified reach; and the bound is never above the merit of *any* configuration for a
target near it (hypothesis, random arms' configurations and target perturbations), while it
decides a pose the tool cannot take at the workspace's edge.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp.reference.bound import lower_bound
from otmm_qp.reference.certificates import recompute
from otmm_qp.reference.chain import chain_of
from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.reference.reach import joint_box
from otmm_qp.reference.settings import ReferenceSettings
from otmm_qp.reference.wrist import carried_points, shorter_chain, wrist_merits
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.robots.planar_arm import PlanarArm
from tests.factories import Hold

ARMS = ["ur5", "panda", "z1"]  # the Z1: an arm the project ships no config for
POSITION, ORIENTATION = 0.02, 0.1


def _random_q(robot: PinocchioArm, rng: np.random.Generator, count: int) -> np.ndarray:
    chain = chain_of(robot)
    lower, upper = joint_box(chain, robot)
    q = np.zeros((count, robot.nv))
    q[:, chain.columns] = rng.uniform(lower, upper, (count, chain.size))
    return q


@pytest.mark.parametrize("name", ARMS)
def test_carried_points_are_the_joint_origins_on_their_circles(name: str) -> None:
    """``o_m = p + R y_c`` exactly; ``o_{m−1}`` on the circle ``p + R Y`` (Pinocchio's FK)."""
    robot = PinocchioArm(name, task="pose")
    chain = chain_of(robot)
    points = carried_points(robot)
    assert len(points) == 2
    import pinocchio as pin

    rng = np.random.default_rng(3)
    joints = [j for j in robot.model.supports[robot.model.frames[robot.frame_id].parentJoint]]
    for q in _random_q(robot, rng, 20):
        configuration = robot.configuration(q)
        pose = np.asarray(robot.forward(configuration))
        p, rotation = pose[:3, 3], pose[:3, :3]
        data = robot.model.createData()
        pin.forwardKinematics(robot.model, data, configuration)
        last, before = (np.asarray(data.oMi[j].translation) for j in (joints[-1], joints[-2]))
        first = points[0]
        assert first.radius == 0.0
        assert np.allclose(p + rotation @ first.centre, last, atol=1e-12)
        second = points[1]
        centre = p + rotation @ second.centre
        axis = rotation @ second.axis
        offset = before - centre
        along = float(offset @ axis)
        across = float(np.linalg.norm(offset - along * axis))
        assert abs(along) <= 1e-12 + 1e-9 * np.linalg.norm(offset)
        assert math.isclose(across, second.radius, rel_tol=1e-9, abs_tol=1e-12)
        # each point's shorter chain has it as its tip
        for drop, point in ((1, first), (2, second)):
            tip = shorter_chain(chain, drop).forward(q[chain.columns][None, :-drop])[0][0]
            assert np.allclose(tip, last if drop == 1 else before, atol=1e-12)
            assert np.allclose(point.base, chain.forward(np.zeros((1, chain.size)))[2][0, 0])


@pytest.mark.parametrize("name", ARMS)
def test_no_sampled_configuration_carries_a_point_past_its_reach(name: str) -> None:
    robot = PinocchioArm(name, task="pose")
    chain = chain_of(robot)
    rng = np.random.default_rng(5)
    for drop, point in zip((1, 2), carried_points(robot), strict=True):
        shorter = shorter_chain(chain, drop)
        lower, upper = joint_box(shorter, robot)
        q = rng.uniform(lower, upper, (40_000, shorter.size))
        corners = rng.integers(0, 2, (10_000, shorter.size))
        q = np.vstack([q, np.where(corners == 1, upper, lower)])
        distance = np.linalg.norm(shorter.forward(q)[0] - point.base, axis=1)
        assert float(np.max(distance)) <= point.outer
        assert point.outer - float(np.max(distance)) < 5e-3  # and tight


@settings(max_examples=40, deadline=None)
@given(
    name=st.sampled_from(ARMS),
    seed=st.integers(0, 2**16),
    shift=st.floats(0.0, 0.6),
    turn=st.floats(0.0, 2.5),
)
def test_the_bound_is_never_above_the_merit_of_any_configuration(
    name: str, seed: int, shift: float, turn: float
) -> None:
    """Targets: a sampled configuration's pose moved by ``shift`` [m] and turned by ``turn``
    [rad]; the bound is at most the merit of that configuration and of 2,000 others."""
    robot = PinocchioArm(name, task="pose")
    chain = chain_of(robot)
    rng = np.random.default_rng(seed)
    q = _random_q(robot, rng, 2_000)
    p, rotations, _, _ = chain.forward(q[:, chain.columns])
    direction = rng.normal(size=3)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    cross = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    spin = np.eye(3) + math.sin(turn) * cross + (1 - math.cos(turn)) * cross @ cross
    target_p = p[0] + shift * direction / np.linalg.norm(direction)
    target_r = rotations[0] @ spin
    bound = wrist_merits(
        carried_points(robot), target_p[None], target_r[None], POSITION, ORIENTATION
    )[0]
    position = np.linalg.norm(p - target_p, axis=1) / POSITION
    relative = np.einsum("ij,njk->nik", target_r, np.transpose(rotations, (0, 2, 1)))
    cosine = np.clip(0.5 * (np.trace(relative, axis1=1, axis2=2) - 1.0), -1.0, 1.0)
    angle = np.arccos(cosine) / ORIENTATION
    merits = np.maximum(position, angle)
    assert bound <= float(np.min(merits)) * (1 + 1e-9) + 1e-9
    # and the merit of the configuration damped least squares reaches from q_0 (near optimal)
    target = np.eye(4)
    target[:3, :3], target[:3, 3] = target_r, target_p
    lower, upper = joint_box(chain, robot)
    joints = q[0].copy()
    for _ in range(40):
        x, jacobian = robot.kinematics(robot.configuration(joints))
        error = robot.task_error(target, x) / np.array([POSITION] * 3 + [ORIENTATION] * 3)
        scaled = np.asarray(jacobian) / np.array([POSITION] * 3 + [ORIENTATION] * 3)[:, None]
        step = scaled.T @ np.linalg.solve(scaled @ scaled.T + 1e-2 * np.eye(6), error)
        joints[chain.columns] = np.clip((joints + step)[chain.columns], lower, upper)
    reached = robot.task_error(target, robot.forward(robot.configuration(joints)))
    merit = max(np.linalg.norm(reached[:3]) / POSITION, np.linalg.norm(reached[3:]) / ORIENTATION)
    assert bound <= merit * (1 + 1e-9) + 1e-9


def _pointing_out(robot: PinocchioArm, orientation: float | None = ORIENTATION) -> TrackingProblem:
    """A pose at the edge of the workspace with the tool pointing away from the base, so the
    wrist would be past its reach (the position alone is reachable)."""
    chain = chain_of(robot)
    first = carried_points(robot)[0]
    base = first.base
    outward = np.array([1.0, 0.0, 0.0])
    rotation = np.eye(3)
    # frame axis that carries the wrist: make R y_c point outward from the base
    y = first.centre / np.linalg.norm(first.centre)
    v = np.cross(y, outward)
    angle = math.atan2(float(np.linalg.norm(v)), float(y @ outward))
    if np.linalg.norm(v) > 1e-12:
        k = v / np.linalg.norm(v)
        cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        rotation = np.eye(3) + math.sin(angle) * cross + (1 - math.cos(angle)) * cross @ cross
    reach = first.outer - 0.5 * float(np.linalg.norm(first.centre))
    pose = np.eye(4)
    pose[:3, :3] = rotation
    pose[:3, 3] = base + reach * outward
    lower, upper = joint_box(chain, robot)
    q0 = np.zeros(robot.nv)
    q0[chain.columns] = np.clip(0.0, lower, upper)
    settings_ = ReferenceSettings(position_tolerance=POSITION, orientation_tolerance=orientation)
    return TrackingProblem(robot, Hold(pose), q0, 0.02, 4.0, settings_)


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_a_tool_pointing_out_at_the_edge_is_certified_and_recomputed(name: str) -> None:
    robot = PinocchioArm(name, task="pose")
    problem = _pointing_out(robot)
    bound = lower_bound(problem)
    wrist = [k for k in range(1, problem.samples) if bound.kinds[k] == "wrist"]
    assert wrist  # once the joints could have got there, the wrist bound is what remains
    sample = wrist[-1]
    assert 1.0 < bound.merit[sample] <= bound.merit[0]  # q_0 is a configuration too
    assert recompute(problem, f"wrist@{sample}") == bound.merit[sample]


def test_no_wrist_bound_without_an_orientation_or_a_chain() -> None:
    """Position tasks and planar arms get none; a pose task without an orientation
    tolerance neither (its merit has no orientation part)."""
    assert carried_points(PlanarArm([0.5, 0.4])) == ()
    robot = PinocchioArm("ur5", task="pose")
    assert "wrist" in lower_bound(_pointing_out(robot)).kinds
    assert "wrist" not in lower_bound(_pointing_out(robot, orientation=None)).kinds
