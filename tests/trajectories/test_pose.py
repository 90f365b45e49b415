"""Pose trajectories: twist = finite difference of position and orientation."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from otmm_qp.exceptions import ConfigError, DimensionError
from otmm_qp.trajectories.circle import CircleTrajectory
from otmm_qp.trajectories.line import ConstantVelocityLineTrajectory, QuinticLineTrajectory
from otmm_qp.trajectories.pose import (
    PoseCircleTrajectory,
    PoseLineTrajectory,
    quaternion_matrix,
    rpy_matrix,
)

START = np.eye(4)
START[:3, :3] = pin.rpy.rpyToMatrix(0.3, -0.2, 1.0)
START[:3, 3] = [0.4, 0.1, 0.5]

TRAJECTORIES = {
    "line_quintic_rpy": PoseLineTrajectory(
        START, 2.0, end=[0.6, -0.2, 0.3], end_rpy=[1.0, 0.2, -0.5]
    ),
    "line_constant_quat": PoseLineTrajectory(
        START,
        2.0,
        end=[0.6, -0.2, 0.3],
        end_quaternion=[0.0, 0.0, 0.3826834, 0.9238795],
        profile="constant",
    ),
    "line_fixed": PoseLineTrajectory(START, 2.0, end=[0.6, -0.2, 0.3]),
    "circle_rpy": PoseCircleTrajectory(
        START, centre=[0.3, 0.0, 0.5], radius=0.15, period=2.0, normal=[0, 1, 1], end_rpy=[0, 0, 0]
    ),
}


@pytest.mark.parametrize("name", sorted(TRAJECTORIES))
def test_twist_is_finite_difference(name: str) -> None:
    trajectory = TRAJECTORIES[name]
    h = 1e-6
    for t in np.linspace(0.05, trajectory.duration - 0.05, 9):
        pose, twist = trajectory.sample(t)
        plus, _ = trajectory.sample(t + h)
        minus, _ = trajectory.sample(t - h)
        np.testing.assert_allclose(twist[:3], (plus[:3, 3] - minus[:3, 3]) / (2 * h), atol=1e-6)
        omega = pin.log3(plus[:3, :3] @ minus[:3, :3].T) / (2 * h)  # world angular velocity
        np.testing.assert_allclose(twist[3:], omega, atol=1e-6)
        np.testing.assert_allclose(pose[:3, :3] @ pose[:3, :3].T, np.eye(3), atol=1e-12)


def test_start_and_end_poses() -> None:
    line = TRAJECTORIES["line_quintic_rpy"]
    np.testing.assert_allclose(line.sample(0.0)[0], START, atol=1e-12)
    end, twist = line.sample(5.0)
    np.testing.assert_allclose(end[:3, 3], [0.6, -0.2, 0.3], atol=1e-12)
    np.testing.assert_allclose(end[:3, :3], pin.rpy.rpyToMatrix(1.0, 0.2, -0.5), atol=1e-12)
    np.testing.assert_array_equal(twist, 0.0)
    fixed = TRAJECTORIES["line_fixed"].sample(1.3)[0]
    np.testing.assert_allclose(fixed[:3, :3], START[:3, :3], atol=1e-12)


def test_orientation_conventions() -> None:
    np.testing.assert_allclose(rpy_matrix([0.3, -0.2, 1.0]), pin.rpy.rpyToMatrix(0.3, -0.2, 1.0))
    quaternion = pin.Quaternion(pin.rpy.rpyToMatrix(0.3, -0.2, 1.0))
    xyzw = [quaternion.x, quaternion.y, quaternion.z, quaternion.w]
    np.testing.assert_allclose(quaternion_matrix(xyzw), quaternion.toRotationMatrix(), atol=1e-12)


def test_position_trajectories_accept_pose_start() -> None:
    for trajectory in (
        QuinticLineTrajectory(START, end=[0.6, -0.2, 0.3], duration=2.0),
        ConstantVelocityLineTrajectory(START, end=[0.6, -0.2, 0.3], duration=2.0),
    ):
        x, v = trajectory.sample(0.0)
        np.testing.assert_allclose(x, START[:3, 3])
        assert v.shape == (3,)
    circle = CircleTrajectory(START, centre=[0.3, 0.1, 0.5], radius=0.1, period=2.0)
    x, v = circle.sample(0.0)
    np.testing.assert_allclose(x, [0.4, 0.1, 0.5], atol=1e-12)
    assert v.shape == (3,)


def test_bad_inputs() -> None:
    with pytest.raises(DimensionError) as info:
        PoseLineTrajectory(np.zeros(3), 1.0)
    assert str(info.value) == "start: expected shape (4, 4), got (3,)"
    with pytest.raises(ConfigError) as error:
        PoseLineTrajectory(START, 1.0, end_rpy=[0, 0, 0], end_quaternion=[0, 0, 0, 1])
    assert str(error.value) == "end_rpy: give at most one of end_rpy and end_quaternion"


@pytest.mark.parametrize("profile", ["quintic", "constant"])
@pytest.mark.parametrize("end_rpy", [None, [0.3, -0.2, 1.0], [3.1, 0.0, 0.0]])
def test_pose_line_window_is_its_samples(profile: str, end_rpy: list[float] | None) -> None:
    # The preview window evaluated at once (Rodrigues about the fixed slerp axis) equals the
    # pose sampled time by time, before the start, during the motion and after its end.
    start = np.eye(4)
    start[:3, 3] = [0.3, 0.1, 0.5]
    trajectory = PoseLineTrajectory(
        start,
        2.0,
        end=[0.5, 0.2, 0.4],
        end_rpy=end_rpy,
        profile=profile,  # type: ignore[arg-type]
    )
    times = np.linspace(-0.5, 3.0, 37)
    window = np.array(trajectory.positions(times))
    one_by_one = np.array([trajectory.position(t) for t in times])
    np.testing.assert_allclose(window, one_by_one, rtol=0.0, atol=1e-12)
