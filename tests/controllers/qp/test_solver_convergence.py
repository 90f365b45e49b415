"""A QP solver that stops before converging is reported as such, never as an infeasible problem.

``qp_scaled``'s problem always has the feasible point ``q̇ = 0, α = 0`` when the joints are
inside their limits; OSQP at 10⁻¹⁰ sometimes exhausts its iterations on it (a near-LP: a 10⁻⁶
Hessian). That used to be raised as ``InfeasibleProblem: ... found no (q̇, α)``.
"""

from __future__ import annotations

import numpy as np
import pytest

from otmm_qp.exceptions import InfeasibleProblem, SolverNotConverged
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.state import KinematicState
from otmm_qp.status import Status
from otmm_qp_controllers.qp import ScaledQpBackend

pytest.importorskip("osqp")


def _problems(
    robot: PinocchioArm, count: int, seed: int
) -> list[tuple[KinematicState, np.ndarray]]:
    """States inside the joint limits and commands from 0.01 to 100 × unit size."""
    rng = np.random.default_rng(seed)
    lower, upper = robot.position_limits
    out = []
    for _ in range(count):
        theta = lower + (upper - lower) * rng.uniform(0.0, 1.0, robot.nv)
        state = KinematicState.compute(robot, robot.configuration(theta))
        out.append((state, rng.standard_normal(robot.task_dim) * 10 ** rng.uniform(-2, 2)))
    return out


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_qp_scaled_osqp_never_calls_a_feasible_problem_infeasible(name: str) -> None:
    robot = PinocchioArm(name=name, task="pose")
    osqp = ScaledQpBackend(solver="osqp")
    daqp = ScaledQpBackend(solver="daqp")
    hold = ScaledQpBackend(solver="osqp", infeasible_policy="hold")
    for backend in (osqp, daqp, hold):
        backend.bind(robot, 0.01)
        backend.reset()
    unconverged = solved = 0
    for state, xdot in _problems(robot, 150, seed=3):
        prev = np.zeros(robot.nv)
        try:
            out = osqp.solve(state, xdot, prev)
        except SolverNotConverged as error:
            assert not isinstance(error, InfeasibleProblem)
            assert "stopped before converging" in str(error) and "not shown infeasible" in str(
                error
            )
            unconverged += 1
            held = hold.solve(state, xdot, prev)  # the hold policy answers it
            assert held.status is Status.INFEASIBLE and np.all(held.qdot == 0.0)
            continue
        solved += 1
        reference = daqp.solve(state, xdot, prev)
        assert abs(out.scale - reference.scale) <= 1e-6  # α: same optimum as the active-set solver
    assert solved > 0.9 * (solved + unconverged)
