"""QpBackend: bounds never violated, DLS equivalence, fast path, solvers, infeasibility."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import qpsolvers
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp.exceptions import InfeasibleProblem, ParameterError, SolverNotFound
from otmm_qp.migration.keywords import from_config
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.state import KinematicState
from otmm_qp_controllers.damping import damped_least_squares
from otmm_qp_controllers.dls import DampedLeastSquaresBackend
from otmm_qp_controllers.qp import QpBackend, QpStep, available_solvers
from otmm_qp_controllers.qp.formulation import QpProblem
from otmm_qp_controllers.qp.solvers import Solution, solve_with_qpsolvers

DT = 0.01
PANDA = PinocchioArm(name="panda", task="pose")


def planar(m: int) -> PlanarArm:
    return PlanarArm([1.0] * m, limits=[[-2.5, 2.5]] * m, velocity_limits=[2.0] * m)


@st.composite
def cases(draw: st.DrawFn) -> tuple[PlanarArm, np.ndarray, np.ndarray, np.ndarray]:
    m = draw(st.integers(2, 5))
    arm = planar(m)
    floats = st.floats(-2.5, 2.5, allow_nan=False)
    theta = np.array(draw(st.lists(floats, min_size=m, max_size=m)))
    if draw(st.booleans()):
        theta[1:] = 0.0  # exactly singular (stretched)
    speed = draw(st.sampled_from([0.01, 1.0, 100.0]))
    xdot = speed * np.array(draw(st.lists(st.floats(-1, 1), min_size=2, max_size=2)))
    prev = np.array(draw(st.lists(st.floats(-2, 2), min_size=m, max_size=m)))
    return arm, theta, xdot, prev


@settings(max_examples=60, deadline=None)
@given(cases(), st.booleans())
def test_bounds_never_violated(case: tuple, accelerate: bool) -> None:
    arm, theta, xdot, prev = case
    limits = [{"type": "position", "gain": 0.5}, {"type": "acceleration", "a_max": 50.0}]
    backend = QpBackend(solver="quadprog", limits=limits if accelerate else None)
    backend.bind(arm, DT)
    state = KinematicState.compute(arm, theta)
    if accelerate:  # |q̇_prev| ≤ a_max·dt keeps 0 in every box: always feasible
        prev = np.clip(prev, -50.0 * DT, 50.0 * DT)
    out = backend.solve(state, xdot, prev)
    lower, upper = arm.position_limits
    assert np.all(np.abs(out.qdot) <= arm.velocity_limits + 1e-12)
    assert np.all(theta + out.qdot * DT <= upper + 1e-12)
    assert np.all(theta + out.qdot * DT >= lower - 1e-12)
    if accelerate:
        assert np.all(np.abs(out.qdot - prev) <= 50.0 * DT + 1e-12)
    assert out.status in ("ok", "bounded")


@settings(max_examples=60, deadline=None)
@given(cases())
def test_fast_path_equals_qp(case: tuple) -> None:
    arm, theta, xdot, prev = case
    state = KinematicState.compute(arm, theta)
    fast = QpBackend(solver="quadprog")
    slow = QpBackend(solver="quadprog", fast_path=False)
    fast.bind(arm, DT)
    slow.bind(arm, DT)
    a, b = fast.solve(state, xdot, prev), slow.solve(state, xdot, prev)
    np.testing.assert_allclose(a.qdot, b.qdot, atol=1e-9)
    assert isinstance(b.details, QpStep) and b.details.problem is not None  # the QP was solved
    assert isinstance(a.details, QpStep)
    np.testing.assert_array_equal(a.details.bounds, b.details.bounds)
    # the plain qpsolvers path on the pure formulation's QP agrees too
    problem = fast.formulation.build(
        state.task_jacobian, xdot, None, a.details.bounds, QpProblem.allocate(arm.nv)
    )
    reference = solve_with_qpsolvers(problem.to_qpsolvers(), "quadprog")
    assert reference is not None
    np.testing.assert_allclose(a.qdot, reference, atol=1e-9)


def test_no_active_limit_equals_dls() -> None:
    rng = np.random.default_rng(1)
    backend = QpBackend(regularization=1e-3, solver="quadprog", fast_path=False)
    backend.bind(PANDA, DT)
    theta = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
    for _ in range(10):
        state = KinematicState.compute(PANDA, PANDA.configuration(theta))
        xdot = 0.02 * rng.standard_normal(6)
        out = backend.solve(state, xdot, np.zeros(7))
        assert out.status == "ok"
        np.testing.assert_allclose(out.qdot, damped_least_squares(state, xdot, 1e-3), atol=1e-8)


@pytest.mark.parametrize("solver", available_solvers())
def test_each_solver_same_answer(solver: str) -> None:
    theta = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
    state = KinematicState.compute(PANDA, PANDA.configuration(theta))
    xdot = np.array([2.0, 0.0, 0.5, 0.0, 0.0, 3.0])  # saturates several joints
    reference = QpBackend(solver="quadprog")
    reference.bind(PANDA, DT)
    expected = reference.solve(state, xdot, np.zeros(7))
    backend = QpBackend(solver=solver)
    backend.bind(PANDA, DT)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for _ in range(3):  # direct paths: init, then warm-started updates
            out = backend.solve(state, xdot, np.zeros(7))
            assert out.status == "bounded"
            assert isinstance(out.details, QpStep) and out.details.problem is not None
            np.testing.assert_allclose(out.qdot, expected.qdot, atol=1e-6)


def _outside_start() -> tuple[PlanarArm, np.ndarray]:
    arm = planar(3)
    return arm, np.array([2.9, 0.3, 0.2])  # 0.4 rad beyond the limit: needs 20 rad/s > 2


def test_infeasible_start_raises() -> None:
    arm, theta = _outside_start()
    backend = QpBackend(solver="daqp")
    backend.bind(arm, DT)
    with pytest.raises(InfeasibleProblem) as info:
        backend.solve(KinematicState.compute(arm, theta), np.zeros(2), np.zeros(3))
    message = str(info.value)
    assert message.startswith("infeasible QP: joint 'joint1': velocity box [-2, 2]")
    assert info.value.step is None  # the backend does not count steps; the loop says which
    assert "\n" not in message
    evidence = info.value.problem  # the step's QP travels with the error
    assert isinstance(evidence, QpProblem)
    assert evidence.lb[0] == -2.0 and evidence.ub[0] == pytest.approx(-0.5 * 0.4 / DT)
    assert info.value.solution is None  # the box was empty: the solver was not called


@pytest.mark.parametrize("policy", ["hold", "dls"])
def test_infeasible_start_policies(policy: str) -> None:
    arm, theta = _outside_start()
    backend = QpBackend(solver="daqp", infeasible_policy=policy)  # type: ignore[arg-type]
    backend.bind(arm, DT)
    state = KinematicState.compute(arm, theta)
    out = backend.solve(state, np.array([0.1, 0.1]), np.zeros(3))
    assert out.status == "relaxed"  # the position bound was given up
    assert out.qdot[0] == pytest.approx(-2.0)  # back toward the limit at full speed
    assert np.all(np.abs(out.qdot) <= 2.0)


def test_unknown_solver_message() -> None:
    with pytest.raises(SolverNotFound) as info:
        QpBackend(solver="gurobi")
    installed = ", ".join(sorted(available_solvers()))
    assert str(info.value) == (
        f"unknown QP solver 'gurobi'; installed: {installed} (pip install 'qpsolvers[<solver>]' "
        "for more)"
    )
    assert set(qpsolvers.available_solvers) <= set(available_solvers())


def test_posture_cost_unconstrained_matches_qp() -> None:
    posture = {"weight": 0.1, "q_nominal": [0.0] * 7}
    backend = QpBackend(solver="quadprog", posture=posture)
    slow = QpBackend(solver="quadprog", posture=posture, fast_path=False)
    backend.bind(PANDA, DT)
    slow.bind(PANDA, DT)
    theta = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
    state = KinematicState.compute(PANDA, PANDA.configuration(theta))
    xdot = np.array([0.01, 0.0, 0.0, 0.0, 0.0, 0.02])
    a, b = backend.solve(state, xdot, np.zeros(7)), slow.solve(state, xdot, np.zeros(7))
    assert isinstance(a.details, QpStep) and a.details.problem is None  # the fast path
    np.testing.assert_allclose(a.qdot, b.qdot, atol=1e-9)


def test_damping_means_lambda_as_in_dls() -> None:
    """``damping: λ`` is the DLS damping factor in qp too (μ = λ²); BackendOutput.damping is λ."""
    theta = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
    state = KinematicState.compute(PANDA, PANDA.configuration(theta))
    xdot = np.full(6, 0.01)
    dls = DampedLeastSquaresBackend(damping=0.02)
    dls.bind(PANDA, DT)
    expected = dls.solve(state, xdot, np.zeros(7))
    for options in ({"damping": 0.02}, {"regularization": 4e-4}):
        with from_config():  # as from a file stating version: 2 (in Python: a FutureWarning)
            backend = QpBackend(solver="daqp", **options)  # type: ignore[arg-type]
        backend.bind(PANDA, DT)
        out = backend.solve(state, xdot, np.zeros(7))
        assert out.damping == pytest.approx(expected.damping) == pytest.approx(0.02)
        np.testing.assert_allclose(out.qdot, expected.qdot, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"damping": 0.1, "regularization": 0.01}, "regularization: give damping (λ) or"),
        ({"damping": 0.0}, "damping: must be a finite number > 0 or None, got 0.0"),
        ({"damping": -0.1}, "damping: must be a finite number > 0 or None, got -0.1"),
        ({"regularization": float("inf")}, "regularization: must be a finite number > 0"),
        ({"damping": "a"}, "damping: must be a finite number > 0 or None, got 'a'"),
    ],
)
def test_damping_options_refused(options: dict, message: str) -> None:
    with pytest.raises(ParameterError) as info:
        QpBackend(**options)
    assert str(info.value).startswith(message)


class _FailingSession:
    """A session whose solver never finds a solution (a solver failure on a feasible box)."""

    name = "failing"

    def load(self, problem: QpProblem) -> None:
        self.problem = problem

    def reset(self) -> None:
        pass

    def solve(self) -> Solution:
        return Solution(None, False, "exitflag -1")


def test_solver_failure_carries_problem_and_answer() -> None:
    backend = QpBackend(solver="daqp", fast_path=False)
    backend.bind(PANDA, DT)
    backend.session = _FailingSession()  # type: ignore[assignment]
    theta = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
    state = KinematicState.compute(PANDA, PANDA.configuration(theta))
    with pytest.raises(InfeasibleProblem) as info:
        backend.solve(state, np.full(6, 0.01), np.zeros(7))
    assert str(info.value) == ("infeasible QP: solver 'daqp' found no solution (exitflag -1)")
    assert info.value.solution == Solution(None, False, "exitflag -1")
    problem = info.value.problem
    assert isinstance(problem, QpProblem)
    np.testing.assert_allclose(
        problem.P, state.task_jacobian.T @ state.task_jacobian + 1e-3 * np.eye(7)
    )  # the default μ = 10⁻³
    holding = QpBackend(solver="daqp", fast_path=False, infeasible_policy="hold")
    holding.bind(PANDA, DT)
    holding.session = _FailingSession()  # type: ignore[assignment]
    out = holding.solve(state, np.full(6, 0.01), np.zeros(7))
    assert out.status == "infeasible"  # the box was not empty: nothing was relaxed
    np.testing.assert_array_equal(out.qdot, np.zeros(7))


def test_the_loop_states_the_step_of_an_infeasible_qp() -> None:
    """The backend raises without a step index; the loop's one line names its step."""
    from otmm_qp.simulation.simulate import failure_message

    arm, theta = _outside_start()
    backend = QpBackend(solver="daqp")
    backend.bind(arm, DT)
    with pytest.raises(InfeasibleProblem) as info:
        backend.solve(KinematicState.compute(arm, theta), np.zeros(2), np.zeros(3))
    line = failure_message(7, info.value)
    assert line.startswith("infeasible QP at step 7: joint 'joint1': velocity box")


@pytest.mark.parametrize(("old", "new"), [("direct_daqp", "daqp"), ("direct_osqp", "osqp")])
def test_a_renamed_solver_name_is_refused_naming_the_new_one(old: str, new: str) -> None:
    from otmm_qp.exceptions import ParameterError

    with pytest.raises(ParameterError) as info:
        QpBackend(solver=old)
    assert str(info.value) == (
        f"solver: {old!r} is now called {new!r} (the persistent {new} session); write solver: {new}"
    )
    assert old not in available_solvers()
