"""The offline-optimal reference: known optima, limits never violated, never worse than warm."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp import registry
from otmm_qp.exceptions import NotWithinJointLimits, ParameterError
from otmm_qp.metrics.metrics import compute_metrics
from otmm_qp.reference import ReferenceResult, ReferenceSettings, as_run, solve_reference
from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.reference.sqp import SequentialQP, SolverFailure
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.robots.robot import Robot
from otmm_qp.trajectories.trajectory import Trajectory
from otmm_qp.trajectories.waypoints import JointWaypointsTrajectory, WaypointsTrajectory

DT = 0.02


class Hold(Trajectory):
    """A fixed target (for tests whose optimum is a distance to a set)."""

    def __init__(self, target: np.ndarray, duration: float) -> None:
        self.target = np.asarray(target, dtype=float)
        self.duration = duration

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        return self.target.copy(), np.zeros_like(self.target)


def check_within_limits(robot: Robot, result: ReferenceResult, speed: float | None) -> None:
    """Position limits and the step limit ``v dt`` hold on every sample (no tolerance)."""
    lower, upper = robot.position_limits
    assert np.all(result.path >= lower) and np.all(result.path <= upper)
    limit = np.asarray(robot.velocity_limits, dtype=float)
    if speed is not None:
        limit = np.minimum(limit, speed)
    assert np.all(np.abs(np.diff(result.path, axis=0)) <= limit * DT)


def test_two_link_past_its_reach_error_is_distance_minus_reach() -> None:
    """Out to 2.1 m and back on a 1.8 m arm: the best error is ``max‖x_d‖ − 1.8`` to 1e-6."""
    robot = PlanarArm([1.0, 0.8])
    q0 = np.array([0.3, 0.6])
    x0 = robot.forward(q0)
    target = 2.1 * x0 / np.linalg.norm(x0)
    trajectory = WaypointsTrajectory(x0, [list(target)], duration=2.0, return_to_start=True)
    settings_ = ReferenceSettings(position_tolerance=0.02, speed_limit=10.0)
    result, problem = solve_reference(robot, trajectory, q0, DT, 2.5, settings_)
    distance = max(float(np.linalg.norm(x)) for x in problem.targets)
    assert result.status == "unachievable" and not result.achievable
    assert result.max_error == pytest.approx(distance - 1.8, abs=1e-6)
    # The bracket is closed: the reach annulus gives the exact optimum from below.
    assert result.bracket.lower <= result.bracket.upper
    assert result.bracket.upper - result.bracket.lower < 1e-6
    assert result.bracket.position_optimum == pytest.approx(distance - 1.8, abs=1e-6)
    # Every sample past the reach is at its own best: the distance to the workspace.
    beyond = np.linalg.norm(np.array(problem.targets), axis=1) - 1.8
    out = beyond > 0.0
    assert np.count_nonzero(out) > 20
    assert np.allclose(np.linalg.norm(result.errors[out], axis=1), beyond[out], atol=1e-6)
    assert result.near_singular  # stretched out: σ_min = 0 at the boundary
    check_within_limits(robot, result, 10.0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fk_of_a_joint_path_inside_the_limits_is_certified(seed: int) -> None:
    """Track the FK of a random joint path within the limits: certificate, error ≈ 0."""
    rng = np.random.default_rng(seed)
    robot = PlanarArm([1.0, 0.8, 0.5], limits=[[-2.5, 2.5], [-2.0, 2.0], [-2.0, 2.0]])
    nodes = [rng.uniform(-1.5, 1.5, 3) for _ in range(3)]
    trajectory = JointWaypointsTrajectory(robot.forward(nodes[0]), robot, nodes, duration=2.0)
    settings_ = ReferenceSettings(position_tolerance=0.01, speed_limit=10.0)
    result, _ = solve_reference(robot, trajectory, nodes[0], DT, 2.2, settings_)
    assert result.status == "achievable" and result.achievable
    assert result.max_error <= 1e-2 * 0.01  # settles at 1 % of the tolerance
    check_within_limits(robot, result, 10.0)


def test_ur5_pose_fk_of_a_joint_path_is_certified(ur5_pose: Robot) -> None:
    lower, upper = ur5_pose.position_limits
    q0 = np.array([0.2, -1.2, 1.3, -1.0, 1.4, 0.3])
    q1 = q0 + np.array([0.6, 0.4, -0.5, 0.3, -0.4, 0.5])
    assert np.all((q1 > lower) & (q1 < upper))
    trajectory = JointWaypointsTrajectory(ur5_pose.forward(q0), ur5_pose, [q0, q1], duration=1.5)
    settings_ = ReferenceSettings(0.02, 0.1, speed_limit=3.0)
    weight = np.array([1.0, 1.0, 1.0, 0.2, 0.2, 0.2])
    result, _ = solve_reference(ur5_pose, trajectory, q0, DT, 2.0, settings_, weight)
    assert result.status == "achievable"
    assert result.max_error <= 2e-4 and result.max_orientation_error <= 1e-3
    check_within_limits(ur5_pose, result, 3.0)


def test_target_outside_the_position_limits_but_inside_the_reach() -> None:
    """Elbow limited to [0.8, 2.5] rad: a point at 1.75 m (reach 1.8 m) is out by r_lim − 1.75."""
    robot = PlanarArm([1.0, 0.8], limits=[[-math.pi, math.pi], [0.8, 2.5]])
    q0 = np.array([0.0, 1.5])
    assert robot.can_reach(np.array([1.75, 0.0]))  # inside the (limit-free) reach
    reach = math.sqrt(1.0 + 0.64 + 1.6 * math.cos(0.8))  # farthest with q2 >= 0.8
    target = np.array([1.75 * math.cos(0.4), 1.75 * math.sin(0.4)])
    settings_ = ReferenceSettings(position_tolerance=0.01, speed_limit=10.0)
    result, _ = solve_reference(robot, Hold(target, 1.0), q0, DT, 1.0, settings_)
    # Certified by sample 0 (q_0 itself, away from the held target), not by the reach.
    assert result.status == "unachievable"
    start_error = float(np.linalg.norm(target - robot.forward(q0)))
    assert result.bracket.lower == pytest.approx(start_error / 0.01, rel=1e-8)
    assert result.bracket.lower <= result.bracket.upper
    assert result.max_error > 0.05
    assert float(np.linalg.norm(result.errors[-1])) == pytest.approx(1.75 - reach, abs=1e-6)
    assert result.touches_position_limit
    check_within_limits(robot, result, 10.0)


@st.composite
def planar_tasks(draw: st.DrawFn) -> tuple[PlanarArm, np.ndarray, Trajectory, float]:
    links = draw(st.integers(2, 3))
    lengths = [draw(st.floats(0.3, 1.2)) for _ in range(links)]
    limits = []
    for _ in range(links):
        low = draw(st.floats(-3.0, -0.2))
        limits.append([low, draw(st.floats(low + 0.4, 3.0))])
    robot = PlanarArm(lengths, limits=limits)
    rng = np.random.default_rng(draw(st.integers(0, 2**31)))
    lower, upper = np.array(limits).T
    q0 = rng.uniform(lower, upper)
    reach = sum(lengths)
    goal = rng.uniform(-1.3 * reach, 1.3 * reach, 2)  # may be out of reach or of the limits
    x0 = robot.forward(q0)
    trajectory = WaypointsTrajectory(x0, [list(goal)], duration=draw(st.floats(0.2, 0.8)))
    return robot, q0, trajectory, draw(st.floats(0.5, 10.0))


@settings(max_examples=12)
@given(planar_tasks())
def test_path_never_violates_a_limit_and_never_loses_to_the_warm_start(
    case: tuple[PlanarArm, np.ndarray, Trajectory, float],
) -> None:
    robot, q0, trajectory, speed = case
    settings_ = ReferenceSettings(position_tolerance=0.01, speed_limit=speed, iterations=4)
    result, problem = solve_reference(robot, trajectory, q0, DT, trajectory.duration, settings_)
    check_within_limits(robot, result, speed)
    assert result.merit <= result.warm_start_merit + 1e-12
    assert np.array_equal(result.path[0], q0)
    assert np.all(np.isfinite(result.path)) and np.all(np.isfinite(result.errors))
    assert (result.status == "achievable") == (result.merit <= 1.0)
    bracket = result.bracket
    assert bracket.lower <= bracket.upper == result.merit
    assert (result.status == "unachievable") == (bracket.lower > 1.0)
    assert bracket.position_optimum <= result.max_error


def test_time_budget_stops_the_solve_with_its_best_path() -> None:
    robot = PlanarArm([1.0, 0.8])
    q0 = np.array([0.3, 0.6])
    x0 = robot.forward(q0)
    trajectory = WaypointsTrajectory(x0, [[2.5, 0.5]], duration=1.0)
    settings_ = ReferenceSettings(position_tolerance=0.01, time_budget=1e-9)
    result, _ = solve_reference(robot, trajectory, q0, DT, 1.0, settings_)
    # Out of the reach annulus: certified by the lower bound, whatever the budget.
    assert result.status == "unachievable" and not result.achievable
    assert result.message is not None and "time budget" in result.message
    check_within_limits(robot, result, None)


def test_solver_failure_is_a_failed_state(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*args: object, **kwargs: object) -> None:
        raise SolverFailure("OSQP status 'primal infeasible'")

    monkeypatch.setattr(SequentialQP, "_solve", refuse)
    robot = PlanarArm([1.0, 0.8])
    q0 = np.array([0.3, 0.6])
    trajectory = WaypointsTrajectory(robot.forward(q0), [[2.5, 0.5]], duration=1.0)
    result, _ = solve_reference(robot, trajectory, q0, DT, 1.0, ReferenceSettings())
    assert result.status == "failed"
    assert result.message is not None and "solver failure" in result.message
    assert result.merit == result.warm_start_merit  # the warm start is kept


def test_run_of_the_path_gives_consistent_metrics() -> None:
    robot = PlanarArm([1.0, 0.8], velocity_limits=[2.0, 2.0])
    q0 = np.array([0.3, 0.6])
    trajectory = WaypointsTrajectory(robot.forward(q0), [[0.2, 1.7]], duration=0.6)
    result, problem = solve_reference(robot, trajectory, q0, DT, 1.0, ReferenceSettings())
    metrics = compute_metrics(as_run(result, problem))
    assert metrics["max_error"] == pytest.approx(result.max_error)
    assert metrics["position_violations"] == 0 and metrics["velocity_violations"] == 0
    assert float(metrics["max_joint_speed"]) <= 2.0
    assert metrics["steps"] == problem.samples == 50
    assert metrics["min_sigma"] == pytest.approx(result.min_sigma)


def test_linearisation_matches_finite_differences(rng: np.random.Generator) -> None:
    """Gradient and Hessian blocks of ½‖S e_k‖² against central differences (planar arm)."""
    robot = PlanarArm([1.0, 0.8, 0.5])
    q0 = np.zeros(3)
    problem = TrackingProblem(
        robot, Hold(np.array([1.9, 0.9]), 0.1), q0, DT, 0.1, ReferenceSettings()
    )
    path = rng.uniform(-1.0, 1.0, (problem.samples, 3))
    _, gradients, hessians = problem.linearise(path)

    def value(q: np.ndarray) -> float:
        e = problem.scale * robot.task_error(problem.targets[1], robot.forward(q))
        return 0.5 * float(e @ e)

    h = 1e-5
    eye = np.eye(3)
    grad = np.array([(value(path[1] + h * u) - value(path[1] - h * u)) / (2 * h) for u in eye])
    assert np.allclose(gradients[0], grad, rtol=1e-6, atol=1e-4)
    hess = np.array(
        [
            [
                (
                    value(path[1] + h * u + h * v)
                    - value(path[1] + h * u - h * v)
                    - value(path[1] - h * u + h * v)
                    + value(path[1] - h * u - h * v)
                )
                / (4 * h * h)
                for v in eye
            ]
            for u in eye
        ]
    )
    assert np.allclose(hessians[0], hess, rtol=1e-4, atol=1e-2)


@pytest.mark.parametrize(
    ("params", "field"),
    [
        ({"position_tolerance": 0.0}, "position_tolerance"),
        ({"orientation_tolerance": math.nan}, "orientation_tolerance"),
        ({"speed_limit": -1.0}, "speed_limit"),
        ({"time_budget": math.inf}, "time_budget"),
        ({"iterations": -1}, "iterations"),
    ],
)
def test_bad_settings_name_the_field(params: dict, field: str) -> None:
    with pytest.raises(ParameterError, match=field) as error:
        ReferenceSettings(**params)
    assert "\n" not in str(error.value)


def test_start_outside_the_limits_is_refused() -> None:
    robot = PlanarArm([1.0, 0.8], limits=[[-1.0, 1.0], [-1.0, 1.0]])
    trajectory = Hold(np.array([1.0, 0.0]), 0.2)
    with pytest.raises(NotWithinJointLimits):
        solve_reference(robot, trajectory, np.array([1.5, 0.0]), DT, 0.2)


@pytest.fixture(scope="module")
def ur5_pose() -> Robot:
    robot: Robot = registry.create(
        registry.ROBOTS, "pinocchio", {"name": "ur5", "task": "pose"}, "r"
    )
    return robot


def test_a_joint_path_task_starts_from_its_own_joint_path() -> None:
    """The trajectory's joint path (within the limits) is a zero-error start."""
    from otmm_qp.reference.warm_start import joint_path_start

    robot = PlanarArm([1.0, 0.8, 0.5], velocity_limits=[3.0, 3.0, 3.0])
    nodes = [np.array([0.1, 0.9, -0.4]), np.array([1.1, -0.6, 0.8])]
    trajectory = JointWaypointsTrajectory(robot.forward(nodes[0]), robot, nodes, duration=1.5)
    problem = TrackingProblem(robot, trajectory, nodes[0], DT, 1.7, ReferenceSettings())
    start = joint_path_start(problem, trajectory)
    assert start is not None
    assert np.max(np.linalg.norm(problem.errors(start), axis=1)) < 1e-12
    assert joint_path_start(problem, Hold(np.zeros(2), 1.0)) is None
    result, _ = solve_reference(robot, trajectory, nodes[0], DT, 1.7)
    assert result.status == "achievable" and result.warm_start_merit < 1e-9
