"""The speed-coupled certificate (issue 40): sound, exact on hand-computed cases, bounded work."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp.exceptions import ParameterError
from otmm_qp.reference import ReferenceSettings
from otmm_qp.reference.bound import lower_bound
from otmm_qp.reference.certificates import recompute
from otmm_qp.reference.coupled_bound import STALL, CoupledSearch, coupled_certificate, merge
from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.reference.sample_bound import SampleSearch
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.robots.robot import Robot
from otmm_qp.trajectories.trajectory import Trajectory

DT = 0.02
TOLERANCE = 0.02  # [m]


class Table(Trajectory):
    """One target per sample ``k = round(t/dt)`` (held after the last)."""

    def __init__(self, targets: Sequence[np.ndarray]) -> None:
        self.targets = [np.asarray(t, dtype=float) for t in targets]

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        target = self.targets[min(int(round(t / DT)), len(self.targets) - 1)]
        return target.copy(), np.zeros(6 if target.ndim == 2 else target.size)


def _problem(robot: Robot, targets: Sequence[np.ndarray], q0: np.ndarray) -> TrackingProblem:
    pose = robot.task_kind == "pose"
    tolerances = ReferenceSettings(
        position_tolerance=TOLERANCE, orientation_tolerance=0.1 if pose else None
    )
    duration = len(targets) * DT
    return TrackingProblem(robot, Table(targets), q0, DT, duration, tolerances)


def _jump(delta: float, at: int) -> tuple[TrackingProblem, float]:
    """A 2-link arm held at ``p(q0)``, the target then moved as joint 1 turned by ``delta``."""
    robot = PlanarArm([0.6, 0.4], velocity_limits=[1.0, 1.0])  # s = 0.02 rad per sample
    q0 = np.array([0.2, 0.9])
    moved = np.array([0.2 + delta, 0.9])
    targets = [robot.forward(q0)] * at + [robot.forward(moved)] * 10
    return _problem(robot, targets, q0), float(np.linalg.norm(targets[-1] - targets[0]))


def test_a_jump_faster_than_the_arm_is_certified_at_the_jump() -> None:
    """By hand: one step moves the frame by at most ``ρ = (l1 + l2) s + l2 s = 0.028`` m, so a
    jump of ``‖A − B‖ > ρ + 2 tol`` cannot be met at both sides: ``R_20 = ∅``, and every
    earlier ``R_k`` holds ``q0`` (merit 0). Each sample alone is reachable, so neither the
    closed-form bounds nor the per-sample search decide it."""
    problem, gap = _jump(0.3, 20)
    assert gap > 0.028 + 2 * TOLERANCE
    assert lower_bound(problem).value <= 1.0
    assert SampleSearch(problem).bound(20, 4000).merit <= 1.0
    outcome = CoupledSearch(problem).run()
    assert outcome.sample == 20
    assert outcome.merit > 1.0
    certified = coupled_certificate(problem, lower_bound(problem))
    assert certified.certificate == "coupled@20"
    assert certified.value == outcome.merit
    assert recompute(problem, "coupled@20") == outcome.merit


def test_a_jump_within_one_step_is_not_certified() -> None:
    """Turning joint 1 by half a step at the jump is a path with merit 0: no certificate."""
    problem, _ = _jump(0.5 * 0.02, 20)
    outcome = CoupledSearch(problem).run()
    assert outcome.sample is None
    assert outcome.merit == 0.0


def test_a_stopped_propagation_certifies_nothing() -> None:
    problem, _ = _jump(0.3, 20)
    outcome = CoupledSearch(problem).run(task_boxes=200)
    assert outcome.sample is None
    assert outcome.boxes <= 200  # the budget, counted in boxes
    assert outcome.reached < 20


def test_a_propagation_that_prunes_nothing_stops_at_the_stall() -> None:
    """A tolerance of 10 m keeps every configuration: the set is the speed box each sample."""
    robot = PlanarArm([0.6, 0.4], velocity_limits=[1.0, 1.0])
    q0 = np.array([0.2, 0.9])
    targets = [robot.forward(q0)] * 40
    problem = TrackingProblem(
        robot, Table(targets), q0, DT, 40 * DT, ReferenceSettings(position_tolerance=10.0)
    )
    outcome = CoupledSearch(problem).run()
    assert outcome.sample is None
    assert outcome.reached == STALL


def test_recompute_refuses_a_malformed_certificate() -> None:
    problem, _ = _jump(0.3, 20)
    for text in ("coupled", "coupled@x", "coupled@999", "magic@3"):
        with pytest.raises(ParameterError, match="reference.certificate"):
            recompute(problem, text)
    assert lower_bound(problem).kinds[0] == "none"  # q0 meets sample 0 exactly
    with pytest.raises(ParameterError, match="sample 0 is 'none'"):
        recompute(problem, "travel@0")
    assert recompute(problem, "none") == 0.0


def test_the_first_set_covers_every_configuration_meeting_the_tolerance() -> None:
    """``R_1`` (refined, then merged) holds every grid point of ``q0 ± s`` with ``m_1 ≤ 1``."""
    robot = PlanarArm([0.6, 0.4], velocity_limits=[3.0, 3.0])
    q0 = np.array([0.2, 0.9])
    target = robot.forward(q0 + np.array([0.05, -0.04]))  # partly out of tolerance at q0 ± s
    problem = _problem(robot, [robot.forward(q0), target, target], q0)
    search = CoupledSearch(problem)
    low, high = q0 - search.widen, q0 + search.widen
    low, high, _, _ = search._refine(1, low[None, :], high[None, :], 600)
    merged_low, merged_high = merge(low, high, 4)
    axes = [
        np.linspace(a, b, 61) for a, b in zip(q0 - search.widen, q0 + search.widen, strict=True)
    ]
    grid = np.array(np.meshgrid(*axes)).reshape(2, -1).T
    merits = problem.merits(np.array([robot.task_error(target, robot.forward(q)) for q in grid]))
    inside = grid[merits <= 1.0]
    assert 0 < inside.shape[0] < grid.shape[0]  # the tolerance cuts the box
    for lows, highs in ((low, high), (merged_low, merged_high)):
        covered = np.any(
            np.all((inside[:, None, :] >= lows) & (inside[:, None, :] <= highs), axis=2), axis=1
        )
        assert covered.all()
    assert low.shape[0] > 0 and merged_low.shape[0] <= 4


@settings(max_examples=25, deadline=None)
@given(
    count=st.integers(1, 60),
    dim=st.integers(1, 6),
    cap=st.integers(1, 12),
    seed=st.integers(0, 2**16),
)
def test_merge_covers_every_box(count: int, dim: int, cap: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    low = rng.uniform(-1.0, 1.0, (count, dim))
    high = low + rng.uniform(0.0, 0.5, (count, dim))
    merged_low, merged_high = merge(low, high, cap)
    assert merged_low.shape[0] == min(count, cap)
    contained = np.all(
        (low[:, None, :] >= merged_low[None]) & (high[:, None, :] <= merged_high[None]), axis=2
    )
    assert contained.any(axis=1).all()


def _walk(robot: Robot, q0: np.ndarray, steps: int, rng: np.random.Generator) -> np.ndarray:
    """A joint path within the position limits moving each joint by ≤ its speed limit × dt."""
    lower, upper = (np.asarray(v, dtype=float) for v in robot.position_limits)
    step = np.asarray(robot.velocity_limits, dtype=float) * DT
    path = [q0]
    for _ in range(steps - 1):
        move = rng.uniform(-1.0, 1.0, q0.size) * step
        path.append(np.clip(path[-1] + move, lower, upper))
    return np.array(path)


@settings(max_examples=12, deadline=None)
@given(
    lengths=st.lists(st.floats(0.2, 0.8), min_size=2, max_size=3),
    seed=st.integers(0, 2**16),
    offset=st.floats(0.0, 0.9),
)
def test_a_path_meeting_the_tolerance_is_never_certified_planar(
    lengths: list[float], seed: int, offset: float
) -> None:
    """Soundness: targets within ``offset × tol`` of a path at full speed — never certified."""
    rng = np.random.default_rng(seed)
    robot = PlanarArm(lengths, velocity_limits=[2.0] * len(lengths))
    q0 = rng.uniform(-2.0, 2.0, len(lengths))
    path = _walk(robot, q0, 25, rng)
    directions = rng.normal(size=(25, 2))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    targets = [
        robot.forward(q) + offset * TOLERANCE * d for q, d in zip(path, directions, strict=True)
    ]
    targets[0] = robot.forward(q0)
    problem = _problem(robot, targets, q0)
    assert float(np.max(problem.merits(problem.errors(path)))) <= 1.0
    outcome = CoupledSearch(problem).run(sample_boxes=800, task_boxes=12_000, cap=48)
    assert outcome.sample is None


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_a_path_meeting_the_tolerance_is_never_certified_pose(name: str) -> None:
    """Soundness on 6-D pose tasks: a random full-speed joint path's own poses as targets."""
    robot = PinocchioArm(name, task="pose")
    rng = np.random.default_rng(7)
    lower, upper = (np.asarray(v, dtype=float) for v in robot.position_limits)
    q0 = 0.5 * (lower + upper) + rng.uniform(-0.3, 0.3, robot.nv)
    path = _walk(robot, q0, 12, rng)
    targets = [np.asarray(robot.forward(robot.configuration(q))) for q in path]
    problem = _problem(robot, targets, q0)
    assert float(np.max(problem.merits(problem.errors(path)))) <= 1.0
    outcome = CoupledSearch(problem).run(sample_boxes=1500, task_boxes=15_000, cap=32)
    assert outcome.sample is None


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_the_enclosure_is_below_the_merit_of_every_configuration_in_its_box(name: str) -> None:
    """The position and tool-axis enclosures of :meth:`SampleSearch.evaluate` hold pointwise."""
    robot = PinocchioArm(name, task="pose")
    rng = np.random.default_rng(11)
    lower, upper = (np.asarray(v, dtype=float) for v in robot.position_limits)
    q0 = 0.5 * (lower + upper)
    target = np.asarray(robot.forward(robot.configuration(q0 + rng.uniform(-0.2, 0.2, robot.nv))))
    problem = _problem(robot, [np.asarray(robot.forward(robot.configuration(q0))), target], q0)
    search = SampleSearch(problem)
    columns = search.chain.columns
    centres = q0[columns] + rng.uniform(-0.3, 0.3, (60, columns.size))
    halves = rng.uniform(0.0, 0.15, (60, columns.size))
    _, low, _ = search.evaluate(1, centres, halves)
    for centre, half, bound in zip(centres, halves, low, strict=True):
        points = centre + rng.uniform(-1.0, 1.0, (40, columns.size)) * half
        configurations = np.tile(q0, (40, 1))
        configurations[:, columns] = points
        errors = np.array([robot.task_error(target, robot.forward(q)) for q in configurations])
        assert bound <= float(np.min(problem.merits(errors)))
    assert float(np.max(low)) > 0.0  # the bound is not trivially 0


@settings(max_examples=6, deadline=None)
@given(
    lengths=st.lists(st.floats(0.3, 0.9), min_size=2, max_size=3),
    seed=st.integers(0, 2**16),
    reach=st.floats(0.3, 1.3),
    duration=st.floats(0.4, 2.0),
)
def test_the_references_own_path_is_never_certified_against(
    lengths: list[float], seed: int, reach: float, duration: float
) -> None:
    """Soundness on paths the reference produced: when its best path meets every tolerance
    the propagation certifies nothing; when it certifies, the best path misses (upper > 1)
    and the certified value is below the path's merit."""
    from otmm_qp.reference import solve_reference
    from otmm_qp.trajectories.waypoints import WaypointsTrajectory

    rng = np.random.default_rng(seed)
    robot = PlanarArm(lengths, velocity_limits=[1.5] * len(lengths))
    q0 = rng.uniform(-2.0, 2.0, len(lengths))
    x0 = robot.forward(q0)
    angle = rng.uniform(-np.pi, np.pi)
    goal = reach * sum(lengths) * np.array([np.cos(angle), np.sin(angle)])
    trajectory = WaypointsTrajectory(x0, [goal], duration=duration)
    tolerances = ReferenceSettings(position_tolerance=TOLERANCE, speed_limit=1.5)
    result, problem = solve_reference(robot, trajectory, q0, DT, duration + 0.1, tolerances)
    outcome = CoupledSearch(problem).run(sample_boxes=800, task_boxes=15_000, cap=48)
    merit = float(np.max(problem.merits(result.errors)))
    if merit <= 1.0:
        assert outcome.sample is None
    if outcome.sample is not None:
        assert outcome.merit <= merit
