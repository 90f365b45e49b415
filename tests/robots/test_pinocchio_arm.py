"""PinocchioArm: FK/Jacobian vs finite differences, pose log map, bad inputs."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from otmm_qp.exceptions import DimensionError, FrameNotFound, RobotLoadError
from otmm_qp.robots.pinocchio_arm import ARMS, PinocchioArm

NAMES = sorted(ARMS)


@pytest.fixture(scope="module", params=[(n, t) for n in NAMES for t in ("position", "pose")])
def arm(request: pytest.FixtureRequest) -> PinocchioArm:
    name, task = request.param
    return PinocchioArm(name=name, task=task)


def _random_theta(arm: PinocchioArm, rng: np.random.Generator) -> np.ndarray:
    lower, upper = arm.position_limits
    lo = np.where(np.isfinite(lower), lower, -np.pi)
    hi = np.where(np.isfinite(upper), upper, np.pi)
    return rng.uniform(lo + 0.05 * (hi - lo), hi - 0.05 * (hi - lo))


def test_jacobian_matches_finite_differences(arm: PinocchioArm) -> None:
    rng = np.random.default_rng(7)
    eps = 1e-6
    for _ in range(3):
        q = arm.configuration(_random_theta(arm, rng))
        x, jacobian = arm.kinematics(q)
        assert jacobian.shape == (arm.task_dim, arm.nv)
        numeric = np.empty_like(jacobian)
        for j in range(arm.nv):
            dv = np.zeros(arm.nv)
            dv[j] = eps
            x_plus = arm.forward(arm.integrate(q, dv, 1.0))
            x_minus = arm.forward(arm.integrate(q, -dv, 1.0))
            numeric[:, j] = arm.task_error(x_plus, x_minus) / (2 * eps)
        np.testing.assert_allclose(jacobian, numeric, atol=1e-6)


def test_shapes_and_dofs() -> None:
    panda = PinocchioArm(name="panda")
    assert (panda.nq, panda.nv, panda.frame_name) == (7, 7, "panda_hand_tcp")
    z1 = PinocchioArm(name="z1")
    assert z1.nv == 6 and "jointGripper" not in z1.joint_names
    kinova = PinocchioArm(name="kinova", task="position")
    assert (kinova.nq, kinova.nv) == (9, 6)
    lower, upper = kinova.position_limits
    assert np.isinf(lower[0]) and np.isinf(upper[0])
    x, jacobian = kinova.kinematics(kinova.configuration(np.full(6, 1.0)))
    assert x.shape == (3,) and jacobian.shape == (3, 6)
    pose = PinocchioArm(name="ur5", task="pose")
    x, jacobian = pose.kinematics(pose.configuration(np.zeros(6)))
    assert x.shape == (4, 4) and jacobian.shape == (6, 6)
    assert pose.urdf_path is not None and pose.urdf_path.endswith("ur5_robot.urdf")
    assert PinocchioArm(name="ur3").urdf_path.endswith("ur3_robot.urdf")  # type: ignore[union-attr]


def test_continuous_joint_round_trip() -> None:
    kinova = PinocchioArm(name="kinova")
    theta = np.array([3.0, 2.0, 1.0, -3.0, 3.0, 0.5])
    q = kinova.configuration(theta)
    np.testing.assert_allclose(kinova.joint_coordinates(q), theta, atol=1e-12)
    q2 = kinova.integrate(q, np.full(6, 0.5), 0.2)
    np.testing.assert_allclose(np.linalg.norm(q2[:2]), 1.0, atol=1e-12)


def test_pose_error_is_consistent_log_map() -> None:
    arm = PinocchioArm(name="ur5", task="pose")
    rng = np.random.default_rng(3)
    for _ in range(5):
        x = arm.forward(arm.configuration(_random_theta(arm, rng)))
        target = arm.forward(arm.configuration(_random_theta(arm, rng)))
        error = arm.task_error(target, x)
        # Applying the twist for unit time about the frame origin lands on the target.
        moved = np.eye(4)
        moved[:3, :3] = pin.exp3(error[3:]) @ x[:3, :3]
        moved[:3, 3] = x[:3, 3] + error[:3]
        np.testing.assert_allclose(moved, target, atol=1e-9)
        np.testing.assert_allclose(arm.task_error(x, x), 0.0, atol=1e-12)


def test_feeding_error_as_velocity_converges() -> None:
    arm = PinocchioArm(name="panda", task="pose")
    q = arm.configuration(np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8]))
    target = arm.forward(arm.configuration(np.array([0.3, -0.1, 0.2, -2.0, 0.1, 1.8, 0.5])))
    errors = []
    for _ in range(200):
        x, jacobian = arm.kinematics(q)
        error = arm.task_error(target, x)
        errors.append(np.linalg.norm(error))
        q = arm.integrate(q, np.linalg.pinv(jacobian) @ (5.0 * error), 0.01)
    assert errors[-1] < 1e-3 * errors[0]
    assert all(b <= a + 1e-12 for a, b in zip(errors, errors[1:], strict=False))


def test_can_reach_is_conservative() -> None:
    arm = PinocchioArm(name="ur5", task="position")
    rng = np.random.default_rng(0)
    for _ in range(50):
        assert arm.can_reach(arm.forward(arm.configuration(_random_theta(arm, rng))))
    assert not arm.can_reach(np.array([5.0, 0.0, 0.0]))


def test_unknown_name_lists_valid_names() -> None:
    with pytest.raises(RobotLoadError) as info:
        PinocchioArm(name="ur42")
    assert str(info.value) == (
        "name: unknown robot 'ur42'; valid names: kinova, panda, ur10, ur3, ur5, xarm7, z1"
    )


def test_missing_urdf_names_path(tmp_path: object) -> None:
    path = f"{tmp_path}/missing.urdf"
    with pytest.raises(RobotLoadError) as info:
        PinocchioArm(urdf=path)
    assert str(info.value) == f"urdf: file not found: {path}"


def test_unknown_frame_lists_frames() -> None:
    with pytest.raises(FrameNotFound) as info:
        PinocchioArm(name="ur5", frame="nope")
    message = str(info.value)
    assert message.startswith("unknown frame 'nope'; valid frames: ") and "tool0" in message
    assert "\n" not in message


def test_bad_override_shapes() -> None:
    with pytest.raises(DimensionError) as info:
        PinocchioArm(name="ur5", velocity_limits=[1.0, 2.0])
    assert str(info.value) == "velocity_limits: expected shape (6,), got (2,)"
    with pytest.raises(DimensionError) as info:
        PinocchioArm(name="ur5", position_limits=[[-1.0, 1.0]] * 5)
    assert str(info.value) == "position_limits: expected shape (6, 2), got (5, 2)"


def test_urdf_path_loads_same_model() -> None:
    named = PinocchioArm(name="ur5", task="pose")
    direct = PinocchioArm(urdf=named.urdf_path, frame="tool0", task="pose")
    q = named.configuration(np.array([0.1, -1.0, 1.2, -1.0, 0.5, 0.2]))
    np.testing.assert_allclose(named.forward(q), direct.forward(q), atol=1e-12)
