"""The reference's batched sample kinematics are the per-sample robot calls, bit for bit.

:class:`~otmm_qp.reference.kinematics.SampleKinematics` evaluates the task errors and
Jacobians of many samples with lean Pinocchio calls (no Jacobian where only errors are asked
for, the rotations of all samples in one NumPy product). The reference's iterates, and so a
study's stored references, stay the same only if every number is the one
``robot.task_error(x_d, robot.kinematics(robot.configuration(q)))`` gives: compared here
exactly, on random configurations of pose and position arms, and on the arms that take the
per-sample definition (continuous joints, a planar arm). The Jacobian derivatives are also
checked against central differences of the Jacobian (the math, not just the old code).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp.exceptions import DimensionError
from otmm_qp.reference.kinematics import SampleKinematics
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.robots.robot import FloatArray, Robot
from tests.factories import joint_waypoints

ROBOTS: dict[str, Callable[[], Robot]] = {
    "ur5 pose": lambda: PinocchioArm("ur5", task="pose"),
    "panda position": lambda: PinocchioArm("panda", task="position"),
    "kinova pose (continuous joints)": lambda: PinocchioArm("kinova", task="pose"),
    "planar": lambda: PlanarArm([1.0, 0.8, 0.5]),
}


def _samples(robot: Robot, seed: int, count: int) -> tuple[FloatArray, list[FloatArray]]:
    """Random joint coordinates ``(count, nv)`` inside the limits and targets near them."""
    rng = np.random.default_rng(seed)
    lower, upper = robot.position_limits
    path = rng.uniform(np.maximum(lower, -3.0), np.minimum(upper, 3.0), (count, robot.nv))
    path[1] = 0.0  # an exactly singular configuration of both arms (stretched wrist)
    nearby = path + rng.normal(0.0, 0.3, path.shape)
    targets = [np.asarray(robot.forward(robot.configuration(q))) for q in nearby]
    return path, targets


@pytest.mark.parametrize("name", list(ROBOTS))
def test_errors_and_jacobians_are_the_per_sample_calls(name: str) -> None:
    robot = ROBOTS[name]()
    path, targets = _samples(robot, 7, 12)
    kinematics = SampleKinematics(robot, targets)
    assert kinematics.lean == (isinstance(robot, PinocchioArm) and robot.nq == robot.nv)
    plain = [robot.kinematics(robot.configuration(q)) for q in path]
    errors = np.array([robot.task_error(t, x) for t, (x, _) in zip(targets, plain, strict=True)])
    jacobians = np.array([jacobian for _, jacobian in plain])
    forward = np.array(
        [
            robot.task_error(t, robot.forward(robot.configuration(q)))
            for t, q in zip(targets, path, strict=True)
        ]
    )

    np.testing.assert_array_equal(kinematics.errors(path), forward)
    np.testing.assert_array_equal(kinematics.errors(path[3:], first=3), forward[3:])
    both = kinematics.errors_and_jacobians(path[2:], first=2)
    np.testing.assert_array_equal(both[0], errors[2:])
    np.testing.assert_array_equal(both[1], jacobians[2:])
    for k in (0, 1, 5):
        error, jacobian = kinematics.sample(path[k], k)
        np.testing.assert_array_equal(error, errors[k])
        np.testing.assert_array_equal(jacobian, jacobians[k])
        assert np.all(np.isfinite(error)) and np.all(np.isfinite(jacobian))


@pytest.mark.parametrize("name", list(ROBOTS))
def test_jacobian_derivatives_are_the_robots_and_its_differences(name: str) -> None:
    robot = ROBOTS[name]()
    path, targets = _samples(robot, 3, 3)
    kinematics = SampleKinematics(robot, targets)
    unit = np.eye(robot.nv)
    step = 1e-6
    for q in path:
        derivatives = kinematics.jacobian_derivatives(q)
        configuration = robot.configuration(q)
        for j in range(robot.nv):
            np.testing.assert_array_equal(
                derivatives[j], robot.jacobian_derivative(configuration, unit[j])
            )
            ahead = robot.jacobian(robot.configuration(q + step * unit[j]))
            behind = robot.jacobian(robot.configuration(q - step * unit[j]))
            # central difference: O(h²) truncation + O(ε/h) rounding, well below 1e-6
            np.testing.assert_allclose(
                derivatives[j], (ahead - behind) / (2.0 * step), rtol=0.0, atol=1e-6
            )


@pytest.mark.parametrize(("links", "duration"), [([1.0, 0.8], 0.04), ([1.0, 0.8, 0.5], 0.3)])
def test_the_cone_programs_rate_rows_are_the_entry_by_entry_ones(
    links: list[float], duration: float
) -> None:
    """``C = [I; D]`` built by sparse sums is the matrix filled entry by entry (``lil``)."""
    import scipy.sparse as sp

    from otmm_qp.reference import ReferenceSettings
    from otmm_qp.reference.conic import ConicEpigraph
    from otmm_qp.reference.problem import TrackingProblem
    from otmm_qp.trajectories.waypoints import JointWaypointsTrajectory

    robot = PlanarArm(links)
    q0 = np.full(robot.nv, 0.3)
    x0 = robot.forward(q0)
    trajectory = JointWaypointsTrajectory(x0, robot, [q0.tolist(), (q0 + 0.2).tolist()], duration)
    problem = TrackingProblem(robot, trajectory, q0, 0.02, duration, ReferenceSettings())
    solver = ConicEpigraph(problem)
    size, nv = solver.size, robot.nv
    diff = sp.identity(size, format="lil")
    for j in range(nv, size):
        diff[j, j - nv] = -1.0
    plain = sp.vstack([sp.identity(size, format="csr"), diff.tocsr()], format="csr")
    built = solver._linear
    assert built.has_canonical_format and built.shape == (2 * size, size)
    for field in ("indptr", "indices", "data"):
        np.testing.assert_array_equal(getattr(built, field), getattr(plain, field))


def test_a_path_of_the_wrong_shape_is_named() -> None:
    robot = ROBOTS["ur5 pose"]()
    path, targets = _samples(robot, 2, 4)
    kinematics = SampleKinematics(robot, targets)
    for wrong, first in ((path[:, :5], 0), (path, 1), (path[0], 0)):
        with pytest.raises(DimensionError, match="path: expected shape"):
            kinematics.errors(wrong, first)
        with pytest.raises(DimensionError, match="path: expected shape"):
            kinematics.errors_and_jacobians(wrong, first)


def _plain_damped_ik(problem: Any) -> FloatArray:
    """The damped-IK start one robot call at a time, ``np.clip`` for the limits (the former
    construction)."""
    from otmm_qp.reference.warm_start import IK_ITERATIONS, RELATIVE_DAMPING

    robot, scale = problem.robot, problem.scale
    path = np.zeros((problem.samples, problem.nv))
    path[0] = problem.q0
    for k in range(1, problem.samples):
        q = path[k - 1].copy()
        for _ in range(IK_ITERATIONS):
            x, jacobian = robot.kinematics(robot.configuration(q))
            error = scale * robot.task_error(problem.targets[k], x)
            scaled = scale[:, None] * jacobian
            gram = scaled @ scaled.T
            damping = (RELATIVE_DAMPING**2) * max(float(np.trace(gram)), 1e-12)
            move = scaled.T @ np.linalg.solve(gram + damping * np.eye(gram.shape[0]), error)
            if not np.all(np.isfinite(move)):
                break
            q = q + move
        step = np.clip(q - path[k - 1], -problem.step, problem.step)
        path[k] = np.clip(path[k - 1] + step, problem.lower, problem.upper)
    return path


@pytest.mark.parametrize("name", ["ur5 pose", "panda position", "planar"])
def test_the_damped_ik_start_is_the_plain_one_and_keeps_the_limits(name: str) -> None:
    from otmm_qp.reference import ReferenceSettings
    from otmm_qp.reference.problem import TrackingProblem
    from otmm_qp.reference.warm_start import damped_ik_path

    robot = ROBOTS[name]()
    rng = np.random.default_rng(5)
    lower, upper = robot.position_limits
    q0 = np.clip(rng.uniform(-1.0, 1.0, robot.nv), lower + 0.1, upper - 0.1)
    trajectory = joint_waypoints(robot, rng, q0, 0.8, 0.4)
    settings = ReferenceSettings(position_tolerance=0.001, speed_limit=1.5)
    problem = TrackingProblem(robot, trajectory, q0, 0.02, 0.4, settings)
    path = damped_ik_path(problem)
    np.testing.assert_array_equal(path, _plain_damped_ik(problem))
    assert np.all(path >= problem.lower) and np.all(path <= problem.upper)
    # within the speed limit after rounding (the step is 1e-9 inside it for that)
    assert np.all(np.abs(np.diff(path, axis=0)) <= problem.speed * problem.dt)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    samples=st.integers(1, 40),
    free=st.booleans(),
)
def test_the_projection_is_the_plain_one_and_keeps_the_limits(
    seed: int, samples: int, free: bool
) -> None:
    """``project_path`` (the trial paths of every trust-region step) against the plain loop."""
    from otmm_qp.reference.projection import project_path

    rng = np.random.default_rng(seed)
    nv = 4
    lower = -np.abs(rng.normal(1.0, 0.5, nv))
    upper = np.abs(rng.normal(1.0, 0.5, nv))
    step = np.abs(rng.normal(0.05, 0.02, nv)) + 1e-3
    if free:  # a continuous joint: no position limit, no step limit
        lower[0], upper[0], step[0] = -np.inf, np.inf, np.inf
    path = np.cumsum(rng.normal(0.0, 0.1, (samples, nv)), axis=0)
    path[0] = np.clip(path[0], lower, upper)
    plain = path.copy()
    for k in range(1, samples):
        move = np.clip(plain[k] - plain[k - 1], -step, step)
        plain[k] = np.clip(plain[k - 1] + move, lower, upper)
    projected = project_path(path, lower, upper, step)
    np.testing.assert_array_equal(projected, plain)
    assert np.all(projected >= lower) and np.all(projected <= upper)
    # each step within its limit up to one rounding of the sum it came from
    assert np.all(np.abs(np.diff(projected, axis=0)) <= step * (1.0 + 1e-12) + 1e-15)
