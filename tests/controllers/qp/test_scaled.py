"""ScaledQpBackend: direction preserved, α maximal, bounds kept, singular J gives stuck."""

from __future__ import annotations

import numpy as np
import pytest

from otmm_qp.exceptions import InfeasibleProblem, SolverNotFound
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.state import KinematicState
from otmm_qp_controllers.qp.box_backend import QpStep
from otmm_qp_controllers.qp.formulation import QpProblem
from otmm_qp_controllers.qp.scaled import SCALED_SOLVERS, ScaledQpBackend
from otmm_qp_controllers.qp.solvers import solve_with_qpsolvers

DT = 0.01
UR5 = PinocchioArm(name="ur5", task="pose")
REGULAR = np.array([0.0, -1.2, 1.5, -1.8, 0.3, 0.0])
WRIST_SINGULAR = np.array([0.0, -1.2, 1.5, -1.8, 0.0, 0.0])


def _solve(theta: np.ndarray, xdot: np.ndarray, solver: str = "quadprog") -> tuple:
    backend = ScaledQpBackend(solver=solver)
    backend.bind(UR5, DT)
    state = KinematicState.compute(UR5, UR5.configuration(theta))
    return backend.solve(state, xdot, np.zeros(6)), state, backend


def test_small_command_fully_realised() -> None:
    xdot = np.array([0.05, 0.0, 0.02, 0.0, 0.1, 0.0])
    out, state, _ = _solve(REGULAR, xdot)
    assert out.scale == 1.0 and out.status == "ok"
    np.testing.assert_allclose(state.task_jacobian @ out.qdot, xdot, atol=1e-12)


@pytest.mark.parametrize("solver", [s for s in SCALED_SOLVERS])
def test_large_command_scaled_in_direction(solver: str) -> None:
    xdot = np.array([2.0, 0.0, 0.0, 0.0, 0.0, 3.0])
    out, state, _ = _solve(REGULAR, xdot, solver)
    assert 0.1 < out.scale < 1.0 and out.status == "bounded"
    np.testing.assert_allclose(state.task_jacobian @ out.qdot, out.scale * xdot, atol=1e-6)
    assert np.all(np.abs(out.qdot) <= UR5.velocity_limits + 1e-12)
    # α is maximal: the pseudoinverse solution scaled by α hits a velocity limit
    direction = np.linalg.solve(state.task_jacobian, xdot)
    alpha_max = float(np.min(UR5.velocity_limits / np.abs(direction)))
    assert out.scale == pytest.approx(min(alpha_max, 1.0), rel=1e-5)


def test_exactly_singular_jacobian_is_stuck_not_crash() -> None:
    state = KinematicState.compute(UR5, UR5.configuration(WRIST_SINGULAR))
    xdot = 0.1 * state.U[:, -1] + 0.05 * state.U[:, 0]  # has a part along the lost direction
    out, state, _ = _solve(WRIST_SINGULAR, xdot)
    assert out.status == "stuck" and out.scale == 0.0
    assert np.all(np.isfinite(out.qdot))
    np.testing.assert_allclose(state.task_jacobian @ out.qdot, 0.0, atol=1e-9)


def test_singular_but_achievable_command_is_realised() -> None:
    backend = ScaledQpBackend(solver="quadprog")
    backend.bind(UR5, DT)
    state = KinematicState.compute(UR5, UR5.configuration(WRIST_SINGULAR))
    xdot = 0.01 * state.U[:, 0]  # lies in range(J)
    out = backend.solve(state, xdot, np.zeros(6))
    assert out.scale == pytest.approx(1.0)
    np.testing.assert_allclose(state.task_jacobian @ out.qdot, xdot, atol=1e-9)
    assert isinstance(out.details, QpStep)  # the fast path (α = 1) or the QP it solved


def test_infeasible_policies() -> None:
    arm = PinocchioArm(name="ur5", task="pose", position_limits=[[-0.1, 0.1]] + [[-7, 7]] * 5)
    theta = np.array([0.5, -1.2, 1.5, -1.8, 0.3, 0.0])  # joint 1 far outside [-0.1, 0.1]
    state = KinematicState.compute(arm, arm.configuration(theta))
    raising = ScaledQpBackend()
    raising.bind(arm, DT)
    with pytest.raises(InfeasibleProblem) as info:
        raising.solve(state, np.zeros(6), np.zeros(6))
    evidence = info.value.problem  # the step's QP travels with the error
    assert isinstance(evidence, QpProblem) and evidence.lb[0] > evidence.ub[0]
    assert info.value.solution is None  # the box was empty: no solver was called
    holding = ScaledQpBackend(infeasible_policy="hold")
    holding.bind(arm, DT)
    out = holding.solve(state, np.zeros(6), np.zeros(6))
    assert out.status == "relaxed" and out.scale == 0.0  # the position bound was given up
    assert out.qdot[0] == pytest.approx(-arm.velocity_limits[0])


def test_proxqp_rejected_with_supported_list() -> None:
    with pytest.raises(SolverNotFound) as info:
        ScaledQpBackend(solver="proxqp")
    assert str(info.value).startswith("unknown QP solver 'proxqp'; installed: clarabel, daqp")


def test_problem_solved_by_qpsolvers_matches() -> None:
    """The exposed pure problem, solved from scratch by qpsolvers, gives the step's answer."""
    xdot = np.array([2.0, 0.0, 0.0, 0.0, 0.0, 3.0])
    out, _, backend = _solve(REGULAR, xdot, "daqp")
    assert isinstance(out.details, QpStep) and out.details.problem is not None
    reference = solve_with_qpsolvers(out.details.problem.to_qpsolvers(), "quadprog")
    assert reference is not None
    np.testing.assert_allclose(out.qdot, reference[:-1], atol=1e-6)
    assert out.scale == pytest.approx(reference[-1], abs=1e-6)
