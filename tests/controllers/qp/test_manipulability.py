"""NEO-style manipulability term in the QP with limits (Haviland & Corke 2021)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp.exceptions import ParameterError
from otmm_qp.robots import PlanarArm
from otmm_qp.state import KinematicState
from otmm_qp_controllers.manipulability import manipulability, manipulability_gradient
from otmm_qp_controllers.qp import QpBackend
from otmm_qp_controllers.qp.manipulability import ManipulabilityQpBackend

LIMITS = [[-2.5, 2.5], [-2.0, 2.0], [-2.0, 2.0], [-2.0, 2.0]]


def arm() -> PlanarArm:
    return PlanarArm([1.0, 0.8, 0.6, 0.5], limits=LIMITS, velocity_limits=[1.0] * 4)


def test_unconstrained_optimum_has_the_linear_term_and_k0_is_qp() -> None:
    robot = arm()
    state = KinematicState.compute(robot, np.array([0.2, 0.3, 0.2, 0.1]))
    xdot = np.array([0.05, 0.1])
    mu, k = 1e-3, 1e-5
    backend = ManipulabilityQpBackend(manipulability_weight=k, regularization=mu)
    backend.bind(robot, 0.01)
    out = backend.solve(state, xdot, np.zeros(4))
    J = state.jacobian
    g = manipulability_gradient(robot, state)
    expected = np.linalg.solve(J.T @ J + mu * np.eye(4), J.T @ xdot + k * g)
    assert np.all(np.abs(expected) < 1.0)  # the box is not active here
    np.testing.assert_allclose(out.qdot, expected, atol=1e-10)
    assert out.damping == pytest.approx(np.sqrt(mu))
    plain = QpBackend(regularization=mu)
    zero = ManipulabilityQpBackend(manipulability_weight=0.0, regularization=mu)
    for b in (plain, zero):
        b.bind(robot, 0.01)
    np.testing.assert_array_equal(
        zero.solve(state, xdot, np.zeros(4)).qdot, plain.solve(state, xdot, np.zeros(4)).qdot
    )


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31 - 1), st.booleans())
def test_limits_hold_and_the_manipulability_rate_grows_with_the_weight(
    seed: int, singular: bool
) -> None:
    rng = np.random.default_rng(seed)
    robot = arm()
    q = rng.uniform(-1.8, 1.8, 4)
    if singular:
        q[1:] = 0.0  # exactly stretched
    state = KinematicState.compute(robot, q)
    xdot = rng.normal(size=2)
    gradient = manipulability_gradient(robot, state)
    rates = []
    for k in (0.0, 0.1, 1.0, 10.0):
        backend = ManipulabilityQpBackend(manipulability_weight=k, infeasible_policy="hold")
        backend.bind(robot, 0.01)
        out = backend.solve(state, xdot, np.zeros(4))
        assert np.all(np.isfinite(out.qdot))
        assert np.all(np.abs(out.qdot) <= 1.0 + 1e-12)  # velocity limits, never violated
        theta = q + 0.01 * out.qdot
        assert np.all(theta >= np.array(LIMITS)[:, 0] - 1e-12)
        assert np.all(theta <= np.array(LIMITS)[:, 1] + 1e-12)
        rates.append(float(gradient @ out.qdot))
    # A larger reward on ẇ = ∇wᵀq̇ never lowers the optimum's ẇ (parametric convex QP).
    assert all(b >= a - 1e-7 for a, b in zip(rates, rates[1:], strict=False))


def test_in_a_run_it_keeps_the_arm_more_manipulable_on_average() -> None:
    from otmm_qp.controller import Controller
    from otmm_qp.simulation.episode import Episode, Loop
    from otmm_qp.simulation.simulate import simulate
    from otmm_qp.trajectories.line import QuinticLineTrajectory

    robot = arm()
    q0 = np.array([0.3, 0.4, 0.3, 0.2])
    line = QuinticLineTrajectory(robot.forward(q0), end=[2.6, 0.4], duration=2.0)
    mean = {}
    for k in (0.0, 1e-3, 1e-2):
        backend = ManipulabilityQpBackend(manipulability_weight=k)
        result = simulate(
            Episode(robot, line, q0, 0.01, 2.0, Loop("clik", 10.0)), Controller("m", [], backend)
        )
        mean[k] = np.mean([manipulability(KinematicState.compute(robot, q)) for q in result.q])
        assert not any(s in ("infeasible", "nonfinite") for s in result.status)
        np.testing.assert_allclose(robot.forward(result.q[-1]), [2.6, 0.4], atol=3e-3)
    # A modest, monotone effect on this arm: mean w 2.081 → 2.092 → 2.106.
    assert mean[0.0] < mean[1e-3] < mean[1e-2]


def test_bad_parameters_name_the_field() -> None:
    with pytest.raises(ParameterError, match="^manipulability_weight: must be a finite number >="):
        ManipulabilityQpBackend(manipulability_weight=-1.0)
    with pytest.raises(ParameterError, match="^damping: must be a finite number > 0"):
        ManipulabilityQpBackend(damping=0.0)
