"""The reference as a certified bracket (issue 26): never beaten, labels certified, bound valid."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp.metrics.metrics import MetricSettings, compute_metrics
from otmm_qp.reference import Candidate, ReferenceSettings, as_run, solve_reference
from otmm_qp.reference.bound import lower_bound
from otmm_qp.reference.independent import slsqp_upper
from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.reference.projection import project_path
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.robots.robot import Robot
from otmm_qp.studies.execute import run_study
from otmm_qp.studies.rows import RELATIVE_ERROR, load_rows
from otmm_qp.studies.spec import parse_study, plan_study
from otmm_qp.trajectories.waypoints import WaypointsTrajectory
from tests.cli_errors import refusal_text
from tests.factories import PINV_ROW, joint_waypoints, reference_study

DT = 0.02

PLANAR = reference_study(
    "bracket-planar",
    seed=1,
    chunk_size=4,
    generators=[
        {"type": "near_singular", "count": 2, "distance": [0.0, 0.1], "duration": [0.8, 1.0]},
        {"type": "beyond_reach", "count": 2, "duration": [0.8, 1.0]},
        {"type": "boundary", "count": 1, "duration": [0.8, 1.0]},
    ],
    controllers=[PINV_ROW, {"name": "qp", "backend": {"type": "qp", "solver": "daqp"}}],
    robots=[{"name": "planar3", "robot": {"type": "planar", "link_lengths": [1.0, 0.8, 0.5]}}],
)

ARMS = {
    "name": "bracket-arms",
    "seed": 2026,
    "dt": 0.05,
    "duration": {"extra": 0.1},
    "chunk_size": 4,
    "time_series": {"tasks": 0},
    "success": {
        "max_position_error": 0.02,
        "max_orientation_error": 0.1,
        "joint_speed_factor": 1.0,
    },
    "reference": {"polish_iterations": 4},
    "robots": [
        {
            "name": "ur5",
            "robot": {"type": "pinocchio", "name": "ur5", "task": "pose"},
            "task_weight": [1.0, 1.0, 1.0, 0.2, 0.2, 0.2],
        },
    ],
    "generators": [
        {"type": "near_singular", "count": 1, "distance": [0.0, 0.08], "duration": [0.6, 0.8]},
        {"type": "beyond_reach", "count": 1, "duration": [0.6, 0.8]},
        {"type": "joint_path", "count": 1, "duration": [0.6, 0.8]},
    ],
    "controllers": [
        {"name": "pinv", "backend": {"type": "pinv"}},
        {"name": "qp", "backend": {"type": "qp", "solver": "daqp"}},
    ],
}


@pytest.fixture(scope="module", params=["planar", "arms"])
def study(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    spec = PLANAR if request.param == "planar" else ARMS
    out = tmp_path_factory.mktemp(request.param)
    run_study(plan_study(parse_study(spec)), out, f"{request.param}.yaml", workers=1)
    return out


@pytest.fixture(scope="module")
def ur5_pose() -> Robot:
    from otmm_qp import registry

    return registry.create(registry.ROBOTS, "pinocchio", {"name": "ur5", "task": "pose"}, "robot")


def test_no_row_within_the_limits_beats_the_reference(study: Path) -> None:
    """Oracle-relative error is defined exactly on the rows that kept every limit, and ≥ 0
    there; a row that broke a limit (speed or position-limit criterion, a step above the
    reference's ``v_max dt``, a joint outside its limits, a stopped run) has it null."""
    config, rows = load_rows(study)
    cap = config.success.max_joint_speed
    limits_broken = 0
    for row in rows.rows:
        value = row[RELATIVE_ERROR]
        if row["controller"] == "oracle":
            assert row["kept_limits"] and value is not None and value >= 0.0
            continue
        faster = (cap is not None and row["max_joint_speed"] > cap) or row["max_speed_ratio"] > 1.0
        broke = faster or row["position_violations"] > 0 or row["status"] != "ok"
        # the row's stored flag, recomputed by the reference's own test on its path
        assert row["within_reference_limits"] is not None
        broke = broke or not row["within_reference_limits"]
        assert row["kept_limits"] is not broke, row["episode_key"]
        assert (value is None) is broke, row["episode_key"]
        if value is not None:
            assert value >= 0.0, row["episode_key"]
        limits_broken += broke
    assert 0 < limits_broken < len(rows.rows)  # both kinds occur: the test can fail


def test_every_label_is_certified(study: Path) -> None:
    """achievable: the stored path, re-scored by the metrics, meets both tolerances within
    every limit; unachievable: the lower bound exceeds the tolerance; always lower ≤ upper."""
    config, rows = load_rows(study)
    success = config.success
    oracle = rows.select(controller="oracle")
    assert oracle
    for row in oracle:
        assert row["reference.lower"] <= row["reference.upper"]
        assert row["reference.max_error"] <= row["max_error"]  # the position optimum
        status = row["reference.status"]
        assert status in ("achievable", "unachievable", "undecided")
        if status == "achievable":
            assert row["max_error"] <= success.max_position_error
            if success.max_orientation_error is not None:
                assert row["max_orientation_error"] <= success.max_orientation_error
            assert row["position_violations"] == 0 and row["velocity_violations"] == 0
            if success.max_joint_speed is not None:
                assert row["max_joint_speed"] <= success.max_joint_speed
            assert row["reference.upper"] <= 1.0
        elif status == "unachievable":
            assert row["reference.lower"] > 1.0
        else:
            assert row["reference.lower"] <= 1.0 < row["reference.upper"]


def test_the_reference_path_passes_its_own_task(study: Path) -> None:
    """Graceful criteria are judged on paths that exist: every oracle row that is not
    ``failed`` succeeds (on an unachievable or undecided task: within ``error_factor`` of its
    own pair of errors); the report's bracket table counts tasks no known path passes."""
    from otmm_qp.studies.verdicts import bracket_summary

    _, rows = load_rows(study)
    oracle = rows.select(controller="oracle")
    assert any(r["reference.status"] != "achievable" for r in oracle)  # graceful is judged
    for row in oracle:
        if row["reference.status"] != "failed":
            assert row["success"], row["episode_key"]
    for robot in rows.robots():
        for line in bracket_summary(rows, robot):
            assert line.unpassed == 0, line


def test_certificates_recompute_from_their_definition(study: Path) -> None:
    """Every task's ``reference.certificate`` (``kind@k``) names a sample whose bound,
    recomputed from the stated definition, is the stored lower bound; unachievable: > 1."""
    from otmm_qp.reference.certificates import recompute
    from otmm_qp.studies.oracle import reference_settings
    from otmm_qp.studies.tradeoff import rebuild_task

    config, rows = load_rows(study)
    checked = 0
    for row in rows.select(controller="oracle"):
        certificate = row["reference.certificate"]
        if certificate == "none":
            assert row["reference.lower"] == 0.0
            continue
        robot, _, task, duration = rebuild_task(config, row)
        settings_ = reference_settings(config)
        problem = TrackingProblem(robot, task.trajectory, task.q0, config.dt, duration, settings_)
        value = recompute(problem, certificate)  # search, coupled or a closed-form kind
        assert value == row["reference.lower"]
        if row["reference.status"] == "unachievable":
            assert value > 1.0
        checked += 1
    assert checked > 0


def test_a_known_better_path_is_adopted_exactly() -> None:
    """A candidate path better than the solver's is the reference, to the last bit."""
    robot = PlanarArm([1.0, 0.8])
    q0 = np.array([0.3, 0.6])
    x0 = robot.forward(q0)
    trajectory = WaypointsTrajectory(x0, [list(2.1 * x0 / np.linalg.norm(x0))], duration=1.0)
    tight = ReferenceSettings(position_tolerance=0.02, speed_limit=10.0, iterations=0)
    result, problem = solve_reference(robot, trajectory, q0, DT, 1.2, tight)
    exact, _ = solve_reference(robot, trajectory, q0, DT, 1.2, ReferenceSettings(speed_limit=10.0))
    errors = problem.errors(exact.path)
    max_error = float(np.max(np.linalg.norm(errors, axis=1)))
    known = Candidate("known", exact.path, errors, max_error)
    adopted, _ = solve_reference(robot, trajectory, q0, DT, 1.2, tight, candidates=[known])
    assert adopted.bracket.position_optimum <= max_error
    assert adopted.merit <= float(np.max(problem.merits(errors)))
    # A faster path than the speed limit allows is no candidate.
    fast = exact.path.copy()
    fast[1:] = fast[-1]
    illegal = Candidate("fast", fast, problem.errors(fast), 0.0)
    refused, _ = solve_reference(robot, trajectory, q0, DT, 1.2, tight, candidates=[illegal])
    assert refused.bracket.source != "fast" and refused.bracket.position_optimum > 0.0


@st.composite
def limited_arms(draw: st.DrawFn) -> tuple[PlanarArm, np.ndarray, float, np.ndarray]:
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
    goal = rng.uniform(-1.4 * sum(lengths), 1.4 * sum(lengths), 2)
    return robot, q0, draw(st.floats(0.5, 6.0)), goal


@settings(max_examples=25, deadline=None)
@given(limited_arms(), st.integers(0, 2**31))
def test_lower_bound_is_below_every_path_within_the_limits(
    case: tuple[PlanarArm, np.ndarray, float, np.ndarray], seed: int
) -> None:
    """No random joint path within the position and speed limits beats the per-sample bound."""
    robot, q0, speed, goal = case
    trajectory = WaypointsTrajectory(robot.forward(q0), [list(goal)], duration=0.6)
    problem = TrackingProblem(
        robot,
        trajectory,
        q0,
        DT,
        0.6,
        ReferenceSettings(position_tolerance=0.01, speed_limit=speed),
    )
    bound = lower_bound(problem)
    rng = np.random.default_rng(seed)
    for _ in range(20):
        walk = np.cumsum(rng.uniform(-1.0, 1.0, (problem.samples, robot.nv)), axis=0)
        walk -= walk[0]  # the path starts at q0
        path = project_path(q0 + walk * problem.step, problem.lower, problem.upper, problem.step)
        error = np.linalg.norm(problem.errors(path), axis=1)
        assert np.all(error >= bound.position - 1e-12)


def test_lower_bound_holds_on_the_ur5_pose(ur5_pose: Robot) -> None:
    """Pose bound (position and geodesic orientation) under random paths within the limits."""
    rng = np.random.default_rng(3)
    lower, upper = ur5_pose.position_limits
    q0 = rng.uniform(np.maximum(lower, -3.0), np.minimum(upper, 3.0))
    x0 = ur5_pose.forward(ur5_pose.configuration(q0))
    far = x0.copy()
    far[:3, 3] = x0[:3, 3] * 1.6  # out of reach, and far to travel
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # π/2 about z
    far[:3, :3] = turn @ x0[:3, :3]
    trajectory = _Hold(far)
    settings_ = ReferenceSettings(position_tolerance=0.02, orientation_tolerance=0.1)
    problem = TrackingProblem(ur5_pose, trajectory, q0, DT, 0.5, settings_)
    bound = lower_bound(problem)
    assert bound.value > 0.0
    for _ in range(10):
        walk = np.cumsum(rng.uniform(-1.0, 1.0, (problem.samples, ur5_pose.nv)), axis=0)
        walk -= walk[0]  # the path starts at q0
        path = project_path(q0 + walk * problem.step, problem.lower, problem.upper, problem.step)
        errors = problem.errors(path)
        assert np.all(np.linalg.norm(errors[:, :3], axis=1) >= bound.position - 1e-12)
        assert np.all(np.linalg.norm(errors[:, 3:], axis=1) >= bound.orientation - 1e-12)
        assert np.all(problem.merits(errors) >= bound.merit - 1e-9)


class _Hold(WaypointsTrajectory):
    """A pose held from t = 0 (the start is away from it: sample 0 is far already)."""

    def __init__(self, target: np.ndarray) -> None:
        self.target = target
        self.duration = 0.5

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        return self.target.copy(), np.zeros(6)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_an_independent_solver_does_not_beat_the_upper_bound_by_5_percent(seed: int) -> None:
    """SLSQP from the damped-IK start and from a random start: ≤ 5 % below ``upper`` on a task
    no path meets; an achievable task is decided by its first certificate (``upper ≤ 1``, not
    sharpened: no verdict depends on it)."""
    rng = np.random.default_rng(seed)
    lengths = rng.uniform(0.4, 1.0, 3)
    limits = [[-2.5, 2.5], [-2.0, 2.4], [-2.2, 2.0]]
    robot = PlanarArm(list(lengths), limits=limits)
    q0 = rng.uniform(-1.5, 1.5, 3)
    x0 = robot.forward(q0)
    goal = x0 + rng.uniform(-1.5, 1.5, 2)
    trajectory = WaypointsTrajectory(x0, [list(goal)], duration=0.3)
    settings_ = ReferenceSettings(position_tolerance=0.02, speed_limit=3.0)
    result, problem = solve_reference(robot, trajectory, q0, DT, 0.3, settings_)
    from otmm_qp.reference.warm_start import damped_ik_path

    noisy = project_path(
        q0 + rng.normal(0.0, 0.3, (problem.samples, 3)), problem.lower, problem.upper, problem.step
    )
    noisy[0] = q0
    other = min(slsqp_upper(problem, damped_ik_path(problem)), slsqp_upper(problem, noisy))
    if result.achievable:
        assert result.bracket.upper <= 1.0 and result.bracket.iterations == 0
    else:
        assert other >= 0.95 * result.bracket.upper - 1e-9
    metrics = compute_metrics(as_run(result, problem), MetricSettings())
    assert metrics["max_error"] == pytest.approx(result.max_error)


FROZEN_URDF = """<robot name="frozen">
  <link name="base"/>
  <link name="l1"/>
  <link name="l2"/>
  <link name="tip"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <axis xyz="0 0 1"/><limit lower="{low}" upper="0.5" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="1 0 0"/><axis xyz="0 0 1"/><limit lower="0" upper="0" effort="1" velocity="1"/>
  </joint>
  <joint name="jt" type="fixed"><parent link="l2"/><child link="tip"/><origin xyz="0.8 0 0"/>
  </joint>
</robot>
"""


@pytest.mark.parametrize(("low", "words"), [("0.5", "lower == upper"), ("0.9", "lower limit")])
def test_a_urdf_whose_limits_leave_no_motion_is_one_line_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], low: str, words: str
) -> None:
    """Every joint frozen (or one reversed): every target but the start is unreachable."""
    import yaml

    from otmm_qp.cli import main

    urdf = tmp_path / "frozen.urdf"
    urdf.write_text(FROZEN_URDF.format(low=low))
    study = dict(
        PLANAR,
        robots=[
            {
                "name": "frozen",
                "robot": {"type": "pinocchio", "urdf": str(urdf), "frame": "tip"},
            }
        ],
    )
    path = tmp_path / "frozen.yaml"
    path.write_text(yaml.safe_dump(study))
    out = tmp_path / "out"
    assert main(["study", str(path), "--out", str(out), "--workers", "1"]) == 2
    err = refusal_text(capsys.readouterr().err)
    assert words in err and "urdf" in err
    assert not out.exists()


@pytest.mark.parametrize("seed", [0, 1])
def test_the_cone_polish_converges_where_the_errors_are_small(ur5_pose: Robot, seed: int) -> None:
    """From a path a little off a reachable one (errors of a few hundredths of a tolerance),
    the cone subproblems converge (KKT test) within every limit, below the start."""
    import math

    from otmm_qp.reference.conic import KKT_TOLERANCE, ConicEpigraph
    from otmm_qp.reference.warm_start import joint_path_start

    rng = np.random.default_rng(seed)
    q0 = rng.uniform(-1.5, 1.5, 6)
    trajectory = joint_waypoints(ur5_pose, rng, q0, 0.2, 0.3)
    tight = ReferenceSettings(position_tolerance=0.02, orientation_tolerance=0.1)
    problem = TrackingProblem(ur5_pose, trajectory, q0, DT, 0.3, tight)
    exact = joint_path_start(problem, trajectory)
    assert exact is not None
    start = exact + rng.normal(0.0, 2e-3, exact.shape)
    start[0] = q0
    start = project_path(start, problem.lower, problem.upper, problem.step)
    first = float(np.max(problem.merits(problem.errors(start))[1:]))
    cone = ConicEpigraph(problem).solve(start, 20, math.inf)
    assert cone.converged and cone.kkt <= KKT_TOLERANCE
    assert problem.limits.keeps(cone.path, problem.errors(cone.path))
    assert cone.merit <= first
    assert cone.merit == pytest.approx(float(np.max(problem.merits(problem.errors(cone.path)))))
