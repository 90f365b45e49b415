"""The cone polish runs Clarabel without its presolve: the same program, the same steps.

Clarabel's presolve only removes constraint rows whose bound is infinite (≥ 1e20); the
cone program of :class:`~otmm_qp.reference.conic.ConicEpigraph` leaves such rows out
itself, so switching presolve off (it saves its set-up) must give the very same solution,
bit for bit — checked on the programs of a real polish (trust radii large and small).
"""

from __future__ import annotations

from typing import Any

import clarabel
import numpy as np
import pytest

from otmm_qp.reference import ReferenceSettings
from otmm_qp.reference.conic import ConicEpigraph, _settings
from otmm_qp.reference.problem import BIG, TrackingProblem
from otmm_qp.reference.warm_start import damped_ik_path
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from tests.factories import joint_waypoints


def _program(radius: float) -> tuple[Any, ...]:
    robot = PinocchioArm("ur5", task="pose")
    rng = np.random.default_rng(11)
    q0 = rng.uniform(-1.0, 1.0, robot.nv)
    trajectory = joint_waypoints(robot, rng, q0, 0.6, 0.4)
    settings = ReferenceSettings(position_tolerance=0.001, orientation_tolerance=0.005)
    problem = TrackingProblem(robot, trajectory, q0, 0.02, 0.4, settings)
    solver = ConicEpigraph(problem)
    path = damped_ik_path(problem)
    local, tie, hessians = solver._linearise(path)
    cone_a, cone_b, dims = solver._cones(local)
    lower, upper = solver._bounds(path, radius)
    up, down = upper < BIG / 2, lower > -BIG / 2
    a = solver._constraints(cone_a, up, down)
    b = np.concatenate([cone_b, upper[up], -lower[down]])
    count = int(np.count_nonzero(up) + np.count_nonzero(down))
    cones = [*(clarabel.SecondOrderConeT(d) for d in dims), clarabel.NonnegativeConeT(count)]
    cost = np.concatenate([tie, [1.0]])
    return solver._hessian(hessians), cost, a, b, cones


@pytest.mark.parametrize("radius", [0.2, 1e-3])
def test_presolve_off_gives_the_same_solution(radius: float) -> None:
    hessian, cost, a, b, cones = _program(radius)
    assert np.all(np.abs(b) < 1e20)  # nothing for the presolve to drop
    ours = _settings()
    assert not ours.presolve_enable
    presolved = _settings()
    presolved.presolve_enable = True
    first = clarabel.DefaultSolver(hessian, cost, a, b, cones, ours).solve()
    second = clarabel.DefaultSolver(hessian, cost, a, b, cones, presolved).solve()
    assert str(first.status) == str(second.status) == "Solved"
    np.testing.assert_array_equal(np.asarray(first.x), np.asarray(second.x))
    np.testing.assert_array_equal(np.asarray(first.z), np.asarray(second.z))
    assert first.iterations == second.iterations
