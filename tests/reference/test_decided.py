"""What the reference leaves unpolished, and why no claim needs it (issue 40's cost).

The position optimum of a pose task is polished on position alone only while its certified
bracket is open by more than ``POSITION_GAP``: within it, the polish could gain at most that
fraction.
"""

from __future__ import annotations

import numpy as np
import pytest

from otmm_qp.reference import ReferenceSettings
from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.trajectories.waypoints import WaypointsTrajectory

DT = 0.02
DURATION = 0.5


def test_the_position_optimum_is_polished_only_where_its_bracket_is_open(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A pose task's position optimum is polished on position alone unless its certified
    bracket is within ``POSITION_GAP``: then the stored value is within that fraction of the
    optimum already (``lower ≤ optimum ≤ value ≤ (1 + gap)·lower``)."""
    from otmm_qp import registry
    from otmm_qp.reference import solve
    from otmm_qp.reference.bound import LowerBound
    from otmm_qp.reference.trust_region import Outcome

    robot = registry.create(registry.ROBOTS, "pinocchio", {"name": "ur5", "task": "pose"}, "r")
    q0 = np.array([0.0, -1.2, 1.5, -1.8, 0.3, 0.0])
    x0 = np.asarray(robot.forward(robot.configuration(q0)))
    trajectory = _Held(x0, DURATION)
    settings = ReferenceSettings(position_tolerance=0.002, orientation_tolerance=0.01)
    problem = TrackingProblem(robot, trajectory, q0, DT, DURATION, settings)
    path = np.repeat(q0[None], problem.samples, axis=0)
    entry = solve._Path(path, problem.errors(path), 5.0, 0.1, "damped_ik")  # 0.1 m: pretend
    calls: list[int] = []

    def polish(self: object, start: np.ndarray, cap: int, deadline: float) -> Outcome:
        calls.append(cap)
        return Outcome(start, 5.0)

    monkeypatch.setattr(solve.ConicEpigraph, "solve", polish)
    for lower, polished in ((0.1 / (1 + 0.5 * solve.POSITION_GAP), False), (0.05, True)):
        calls.clear()
        bound = LowerBound(np.full(problem.samples, lower), *[np.zeros(problem.samples)] * 2)
        value, position_lower = solve._position_optimum(problem, [entry], bound, np.inf)
        assert bool(calls) == polished and position_lower == lower
        assert value <= 0.1 and (polished or value <= (1 + solve.POSITION_GAP) * lower)


class _Held(WaypointsTrajectory):
    """A pose held from t = 0."""

    def __init__(self, target: np.ndarray, duration: float) -> None:
        self.target, self.duration = target, duration

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        return self.target.copy(), np.zeros(6)
