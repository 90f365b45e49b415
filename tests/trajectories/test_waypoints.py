"""Waypoint trajectories and the smooth pose circle: continuity, derivatives, end holds."""

from __future__ import annotations

import numpy as np
import pytest

from otmm_qp.exceptions import OtmmError
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.trajectories.circle import CircleTrajectory
from otmm_qp.trajectories.pose import PoseCircleTrajectory, log_so3, rpy_matrix
from otmm_qp.trajectories.waypoints import JointWaypointsTrajectory, WaypointsTrajectory


def _finite_difference(trajectory, t: float, h: float = 1e-6) -> np.ndarray:
    a, b = trajectory.position(t - h), trajectory.position(t + h)
    if a.ndim == 2:
        linear = (b[:3, 3] - a[:3, 3]) / (2 * h)
        angular = log_so3(b[:3, :3] @ a[:3, :3].T) / (2 * h)
        return np.concatenate((linear, angular))
    return (b - a) / (2 * h)


def test_position_waypoints_pass_points_rest_between_and_return() -> None:
    trajectory = WaypointsTrajectory(
        np.zeros(2), [[1.0, 0.0], [1.0, 1.0]], duration=3.0, return_to_start=True
    )
    bounds = np.concatenate(([0.0], np.cumsum(trajectory.segments.durations)))
    for t, point in zip(bounds, [[0, 0], [1, 0], [1, 1], [0, 0]], strict=True):
        x, v = trajectory.sample(float(t))
        assert np.allclose(x, point) and np.allclose(v, 0.0)
    assert trajectory.duration == pytest.approx(3.0)
    for t in np.linspace(0.05, 2.95, 17):
        assert np.allclose(
            trajectory.sample(float(t))[1], _finite_difference(trajectory, t), atol=1e-5
        )


def test_pose_waypoints_twist_matches_finite_difference() -> None:
    start = np.eye(4)
    start[:3, 3] = [0.3, 0.1, 0.4]
    trajectory = WaypointsTrajectory(
        start, [[0.5, 0.0, 0.3, 0.2, -0.3, 0.5], [0.5, 0.2, 0.3]], segment_durations=[1.0, 2.0]
    )
    for t in np.linspace(0.05, 2.95, 13):
        assert np.allclose(
            trajectory.sample(float(t))[1], _finite_difference(trajectory, t), atol=1e-5
        )
    end = trajectory.position(5.0)
    assert np.allclose(end[:3, :3], rpy_matrix([0.2, -0.3, 0.5]))


def test_joint_waypoints_reference_is_forward_kinematics() -> None:
    arm = PlanarArm([1.0, 0.8])
    nodes = [[0.2, 0.5], [0.4, -0.1], [0.0, 0.3]]
    trajectory = JointWaypointsTrajectory(arm.forward(np.array(nodes[0])), arm, nodes, duration=2.0)
    for t in np.linspace(0.05, 1.95, 9):
        q, _ = trajectory.joint_sample(float(t))
        assert np.allclose(trajectory.position(float(t)), arm.forward(q))
        assert np.allclose(
            trajectory.sample(float(t))[1], _finite_difference(trajectory, t), atol=1e-5
        )
    spec = JointWaypointsTrajectory(
        np.zeros(2), {"type": "planar", "link_lengths": [1.0, 0.8]}, nodes, duration=2.0
    )
    assert np.allclose(spec.position(1.0), trajectory.position(1.0))


@pytest.mark.parametrize(
    "kwargs",
    [
        {"waypoints": []},
        {"waypoints": [[1.0, 2.0, 3.0]]},
        {"waypoints": [[1.0, 0.0]], "duration": 0.0},
    ],
)
def test_bad_waypoints(kwargs: dict) -> None:
    kwargs.setdefault("duration", 1.0)
    with pytest.raises(OtmmError):
        WaypointsTrajectory(np.zeros(2), **kwargs)


def test_pose_circle_starts_at_rest_and_holds_after_its_duration() -> None:
    start = np.eye(4)
    start[:3, 3] = [0.5, 0.0, 0.3]
    trajectory = PoseCircleTrajectory(
        start, [0.3, 0.0, 0.3], 0.2, period=4.0, end_rpy=[0.0, 0.0, 0.5]
    )
    _, twist = trajectory.sample(0.0)
    assert np.allclose(twist, 0.0)
    end, end_twist = trajectory.sample(4.0)
    later, later_twist = trajectory.sample(6.0)
    assert np.allclose(end, later) and np.allclose(later_twist, 0.0) and np.allclose(end_twist, 0.0)
    assert np.allclose(later[:3, :3], rpy_matrix([0.0, 0.0, 0.5]))
    assert np.allclose(later[:3, 3], start[:3, 3])  # one full turn
    for t in np.linspace(0.1, 3.9, 11):
        assert np.allclose(
            trajectory.sample(float(t))[1], _finite_difference(trajectory, t), atol=1e-5
        )


def test_circle_quintic_profile_derivative_and_hold() -> None:
    circle = CircleTrajectory(
        np.array([1.0, 0.0]), [0.0, 0.0], 1.0, 2.0, turns=0.5, profile="quintic"
    )
    assert circle.duration == pytest.approx(1.0)
    assert np.allclose(circle.position(1.0), [-1.0, 0.0], atol=1e-12)
    assert np.allclose(circle.sample(2.0)[1], 0.0)
    for t in np.linspace(0.05, 0.95, 7):
        assert np.allclose(circle.sample(float(t))[1], _finite_difference(circle, t), atol=1e-5)
