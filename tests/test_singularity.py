"""σ_min derivatives and the Jacobian's directional derivative, checked by finite differences."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.robots.robot import Robot
from otmm_qp.singularity import sigma_min_gradient, sigma_min_rate
from otmm_qp.state import KinematicState


def _fd_jacobian_rate(robot: Robot, q: np.ndarray, d: np.ndarray, h: float = 1e-6) -> np.ndarray:
    forward = robot.jacobian(robot.integrate(q, d, h))
    backward = robot.jacobian(robot.integrate(q, d, -h))
    return (forward - backward) / (2 * h)


def _fd_sigma_gradient(robot: Robot, q: np.ndarray, weight: np.ndarray | None) -> np.ndarray:
    h = 1e-6
    out = np.zeros(robot.nv)
    for k in range(robot.nv):
        e = np.zeros(robot.nv)
        e[k] = 1.0
        plus = KinematicState.compute(robot, robot.integrate(q, e, h), weight).sigma_min
        minus = KinematicState.compute(robot, robot.integrate(q, e, -h), weight).sigma_min
        out[k] = (plus - minus) / (2 * h)
    return out


@settings(max_examples=40, deadline=None)
@given(
    lengths=st.lists(st.floats(0.2, 2.0), min_size=2, max_size=5),
    seed=st.integers(0, 2**31 - 1),
)
def test_planar_jacobian_derivative_matches_finite_differences(lengths, seed):
    robot = PlanarArm(lengths)
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, robot.nv)
    d = rng.normal(size=robot.nv)
    np.testing.assert_allclose(
        robot.jacobian_derivative(q, d), _fd_jacobian_rate(robot, q, d), atol=1e-6
    )


@pytest.mark.parametrize(
    ("name", "task"), [("ur5", "pose"), ("panda", "pose"), ("kinova", "pose"), ("ur5", "position")]
)
def test_pinocchio_jacobian_derivative_matches_finite_differences(name, task):
    robot = PinocchioArm(name=name, task=task)
    rng = np.random.default_rng(3)
    for _ in range(3):
        theta = rng.uniform(-1.0, 1.0, robot.nv)
        q = robot.configuration(theta)
        d = rng.normal(size=robot.nv)
        analytic = robot.jacobian_derivative(q, d)
        # The base-class central difference is the independent reference.
        reference = Robot.jacobian_derivative(robot, q, d)
        np.testing.assert_allclose(analytic, reference, atol=2e-6)


@pytest.mark.parametrize("weighted", [False, True])
def test_sigma_min_gradient_matches_finite_differences_ur5(weighted):
    robot = PinocchioArm(name="ur5", task="pose")
    weight = np.array([1, 1, 1, 0.2, 0.2, 0.2]) if weighted else None
    q = robot.configuration(np.array([0.0, -1.2, 1.5, -1.8, 0.3, 0.0]))
    state = KinematicState.compute(robot, q, weight)
    np.testing.assert_allclose(
        sigma_min_gradient(robot, state), _fd_sigma_gradient(robot, q, weight), atol=1e-6
    )


def test_sigma_min_rate_is_gradient_along_qdot():
    robot = PlanarArm([1.0, 0.8])
    q = np.array([0.4, 0.7])
    state = KinematicState.compute(robot, q)
    qdot = np.array([0.3, -1.1])
    gradient = sigma_min_gradient(robot, state)
    assert sigma_min_rate(robot, state, qdot) == pytest.approx(gradient @ qdot, abs=1e-12)
    np.testing.assert_allclose(gradient, _fd_sigma_gradient(robot, q, None), atol=1e-7)


def test_two_link_sigma_gradient_points_away_from_stretch():
    # σ_min of the 2-link arm vanishes at q2 = 0; increasing |q2| from a small value raises it.
    robot = PlanarArm([1.0, 0.8])
    state = KinematicState.compute(robot, np.array([0.2, 0.1]))
    assert sigma_min_gradient(robot, state)[1] > 0.0


def test_structurally_singular_arm_has_zero_derivatives():
    robot = PlanarArm([1.0])  # one joint, two task rows: σ_min ≡ 0
    state = KinematicState.compute(robot, np.array([0.3]))
    assert state.sigma_min == 0.0
    np.testing.assert_array_equal(sigma_min_gradient(robot, state), [0.0])
    assert sigma_min_rate(robot, state, np.array([1.0])) == 0.0
