"""The cone polish's subproblem assembly: the vectorised matrices are the plain ones, bit for bit.

:class:`~otmm_qp.reference.conic.ConicEpigraph` builds its cone rows, Hessian and stacked
constraint matrix with array operations and keeps the stacked matrix while the
linearisation and the finite rows stay the same. Each is compared here with the plain
construction it replaces (one cone at a time, ``scipy.sparse.block_diag`` and ``vstack``):
the same canonical CSC arrays exactly, so Clarabel sees the same program and a study's
references do not move.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
import scipy.sparse as sp

from otmm_qp import registry
from otmm_qp.reference import ReferenceSettings
from otmm_qp.reference.conic import ConicEpigraph
from otmm_qp.reference.problem import BIG, TrackingProblem
from otmm_qp.reference.projection import project_path
from otmm_qp.reference.warm_start import damped_ik_path
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.robots.robot import Robot
from tests.factories import joint_waypoints

DT = 0.02


def _plain_cones(solver: ConicEpigraph, local: list[Any]) -> tuple[sp.csc_matrix, Any, list[int]]:
    """One cone per (block, part), appended in order: the construction the solver replaces."""
    nv, size = solver.problem.nv, solver.size
    rows, cols, vals, rhs, dims = [], [], [], [], []
    row = 0
    for b, (error, jacobian) in enumerate(local):
        for rows_p, tolerance in solver.parts:
            part_j = jacobian[rows_p] / tolerance
            d = part_j.shape[0]
            rows.append(np.array([row]))
            cols.append(np.array([size]))
            vals.append(np.array([-1.0]))
            r, c = np.meshgrid(np.arange(d), np.arange(nv), indexing="ij")
            rows.append((row + 1 + r).ravel())
            cols.append((b * nv + c).ravel())
            vals.append(part_j.ravel())
            rhs.append(0.0)
            rhs.extend((error[rows_p] / tolerance).tolist())
            dims.append(d + 1)
            row += d + 1
    matrix = sp.csc_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(row, size + 1),
    )
    return matrix, np.asarray(rhs), dims


def _same(a: sp.spmatrix, b: sp.spmatrix) -> None:
    a, b = sp.csc_matrix(a), sp.csc_matrix(b)
    assert a.shape == b.shape
    assert a.has_canonical_format and b.has_canonical_format
    np.testing.assert_array_equal(a.indptr, b.indptr)
    np.testing.assert_array_equal(a.indices, b.indices)
    np.testing.assert_array_equal(a.data, b.data)


def _ur5() -> Robot:
    return registry.create(registry.ROBOTS, "pinocchio", {"name": "ur5", "task": "pose"}, "robot")


def _problem(robot: Robot, seed: int, settings: ReferenceSettings) -> TrackingProblem:
    rng = np.random.default_rng(seed)
    q0 = np.clip(rng.uniform(-1.0, 1.0, robot.nv), -2.0, 2.0)
    trajectory = joint_waypoints(robot, rng, q0, 0.5, 0.3)
    return TrackingProblem(robot, trajectory, q0, DT, 0.3, settings)


CASES = [
    ("ur5 pose", _ur5, ReferenceSettings(position_tolerance=0.002, orientation_tolerance=0.01)),
    ("ur5 position only", _ur5, ReferenceSettings(position_tolerance=0.002)),
    (
        "planar, speed capped",
        lambda: PlanarArm([1.0, 0.8, 0.5]),
        ReferenceSettings(position_tolerance=0.001, speed_limit=2.0),
    ),
]


@pytest.mark.parametrize(("name", "robot", "settings"), CASES, ids=[c[0] for c in CASES])
@pytest.mark.parametrize("seed", [0, 1])
def test_the_assembled_program_is_the_plain_one(
    name: str, robot: Any, settings: ReferenceSettings, seed: int
) -> None:
    problem = _problem(robot(), seed, settings)
    solver = ConicEpigraph(problem)
    rng = np.random.default_rng(seed)
    path = damped_ik_path(problem) + rng.normal(0.0, 0.05, (problem.samples, problem.nv))
    path[0] = problem.q0
    path = project_path(path, problem.lower, problem.upper, problem.step)
    local, _, hessians = solver._linearise(path)

    cones = solver._cones(local)
    plain = _plain_cones(solver, local)
    _same(cones[0], plain[0])
    np.testing.assert_array_equal(cones[1], plain[1])
    assert cones[2] == plain[2]

    hessians[0, 0, 1] = hessians[0, 1, 0] = 0.0  # a zero entry is stored, as block_diag does
    expected = sp.triu(
        sp.block_diag([*(0.5 * (h + h.T) for h in hessians), sp.csc_matrix((1, 1))], format="csc"),
        format="csc",
    )
    _same(solver._hessian(hessians), expected)

    for radius in (0.2, 1e-3):
        lower, upper = solver._bounds(path, radius)
        up, down = upper < BIG / 2, lower > -BIG / 2
        linear = sp.hstack([solver._linear, sp.csc_matrix((2 * solver.size, 1))], format="csr")
        stacked = sp.vstack([plain[0], linear[up], -linear[down]], format="csc")
        _same(solver._constraints(cones[0], up, down), stacked)
    # a new linearisation is stacked anew (the kept matrix is not reused for it)
    moved = path.copy()
    moved[1:] += 0.01
    other = solver._cones(solver._linearise(moved)[0])
    lower, upper = solver._bounds(moved, 0.2)
    up, down = upper < BIG / 2, lower > -BIG / 2
    linear = sp.hstack([solver._linear, sp.csc_matrix((2 * solver.size, 1))], format="csr")
    _same(
        solver._constraints(other[0], up, down),
        sp.vstack([other[0], linear[up], -linear[down]], format="csc"),
    )
    # fewer finite rows: the stacked rows follow
    fewer = up.copy()
    fewer[-1] = False
    _same(
        solver._constraints(other[0], fewer, down),
        sp.vstack([other[0], linear[fewer], -linear[down]], format="csc"),
    )


def test_a_solve_is_deterministic_and_keeps_the_limits() -> None:
    """Two solves from the same start give the same path to the bit (nothing kept between
    solves changes the program), within every limit and no worse than the start."""
    settings = ReferenceSettings(position_tolerance=0.002, orientation_tolerance=0.01)
    problem = _problem(_ur5(), 3, settings)
    start = damped_ik_path(problem)
    solver = ConicEpigraph(problem)
    first = solver.solve(start, 6, math.inf)
    again = solver.solve(start, 6, math.inf)
    fresh = ConicEpigraph(problem).solve(start, 6, math.inf)
    np.testing.assert_array_equal(first.path, again.path)
    np.testing.assert_array_equal(first.path, fresh.path)
    assert first.iterations == fresh.iterations and first.kkt == fresh.kkt
    assert problem.limits.keeps(first.path, problem.errors(first.path))
    start_merit = float(np.max(problem.merits(problem.errors(start))[1:]))
    assert first.merit <= start_merit


def test_stall_stops_a_crawl_that_cannot_reach_the_tolerance() -> None:
    """The stall test: a crawl (gain < 1e-3 of the merit over 3 accepted steps) stops, unless
    crawling on for the remaining iterations could bring the merit to 1 (a label could move);
    real progress never stops."""
    from otmm_qp.reference.trust_region import STALL_GAIN, STALL_WINDOW, stalled

    crawl = [7.5 - 1e-4 * j for j in range(STALL_WINDOW + 1)]
    assert stalled(crawl, 10)
    assert not stalled(crawl[:STALL_WINDOW], 10)  # too few steps to judge
    progress = [7.5 * (1 - 2 * STALL_GAIN) ** j for j in range(STALL_WINDOW + 1)]
    assert not stalled(progress, 10)
    near = [1.002 - 1e-4 * j for j in range(STALL_WINDOW + 1)]  # 1.0017: 1e-4/step x 20 > gap
    assert stalled(near, 5) and not stalled(near, 20)
