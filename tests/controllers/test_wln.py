"""Weighted least-norm joint-limit avoidance (Chan & Dubey 1995)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp.exceptions import ParameterError
from otmm_qp.robots import PlanarArm
from otmm_qp.state import KinematicState
from otmm_qp_controllers.damping import damped_least_squares
from otmm_qp_controllers.wln import WeightedLeastNormBackend, limit_cost_gradient

LIMITS = [[-2.0, 2.0], [-1.5, 2.5], [-2.0, 1.0], [-1.0, 1.0]]


def cost(theta: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> float:
    return float(np.sum((upper - lower) ** 2 / (4 * (upper - theta) * (theta - lower))))


@settings(max_examples=40)
@given(st.lists(st.floats(0.05, 0.95), min_size=4, max_size=4))
def test_gradient_is_the_derivative_of_chan_and_dubeys_cost(fractions: list[float]) -> None:
    lower, upper = np.array(LIMITS).T
    theta = lower + np.array(fractions) * (upper - lower)
    h = 1e-7
    fd = [
        abs(cost(theta + h * e, lower, upper) - cost(theta - h * e, lower, upper)) / (2 * h)
        for e in np.eye(4)
    ]
    np.testing.assert_allclose(limit_cost_gradient(theta, lower, upper), fd, rtol=1e-5, atol=1e-6)


def test_gradient_at_and_beyond_limits_and_without_limits() -> None:
    lower, upper = np.array([-1.0, -1.0, -np.inf]), np.array([1.0, 1.0, np.inf])
    g = limit_cost_gradient(np.array([1.0, 1.5, 7.0]), lower, upper)
    assert g[0] == np.inf and g[1] == np.inf and g[2] == 0.0


@settings(max_examples=40)
@given(
    st.integers(0, 2**31 - 1),
    st.sampled_from([0.0, 0.05]),
    st.booleans(),
)
def test_solution_is_the_weighted_least_norm_one(seed: int, damping: float, singular: bool) -> None:
    rng = np.random.default_rng(seed)
    arm = PlanarArm([1.0, 0.8, 0.6, 0.5], limits=LIMITS)
    lower, upper = np.array(LIMITS).T
    theta = lower + rng.uniform(0.05, 0.95, 4) * (upper - lower)
    if singular:
        theta[1:] = 0.0  # exactly stretched
    backend = WeightedLeastNormBackend(damping=damping)
    backend.bind(arm, 0.01)
    state = KinematicState.compute(arm, theta)
    xdot = rng.normal(size=2)
    out = backend.solve(state, xdot, np.zeros(4))
    assert np.all(np.isfinite(out.qdot))
    w = 1.0 + limit_cost_gradient(theta, lower, upper)  # first step from rest: all "toward"
    J = state.jacobian
    Winv = np.diag(1.0 / w)
    if damping > 0.0:
        expected = Winv @ J.T @ np.linalg.solve(J @ Winv @ J.T + damping**2 * np.eye(2), xdot)
        np.testing.assert_allclose(out.qdot, expected, atol=1e-9)
    elif not singular:
        np.testing.assert_allclose(J @ out.qdot, xdot, atol=1e-9)
        # The least W-norm among exact solutions: below the plain pseudoinverse's W-norm.
        plain = np.linalg.pinv(J) @ xdot
        assert out.qdot @ (w * out.qdot) <= plain @ (w * plain) + 1e-12


def test_moving_away_from_a_limit_releases_the_joint() -> None:
    arm = PlanarArm([1.0, 0.8, 0.6], limits=LIMITS[:3])
    backend = WeightedLeastNormBackend()
    backend.bind(arm, 0.01)
    near = np.array([0.3, 2.3, -0.5])  # joint 2 close to its upper limit 2.5
    xdot = np.array([0.2, -0.1])
    first = backend.weights(KinematicState.compute(arm, near), np.zeros(3))
    assert first[1] > 10.0  # toward (first step from rest): heavily weighted
    away = near - np.array([0.0, 0.05, 0.0])  # it moved away: |∂H/∂θ| fell
    second = backend.weights(KinematicState.compute(arm, away), np.zeros(3))
    assert second[1] == 1.0
    closer = away + np.array([0.0, 0.02, 0.0])  # and back toward it
    third = backend.weights(KinematicState.compute(arm, closer), np.zeros(3))
    assert third[1] > 10.0
    backend.reset()
    # No history: the sign of the previous velocity decides.
    leaving = backend.weights(KinematicState.compute(arm, near), np.array([0.0, -0.3, 0.0]))
    assert leaving[1] == 1.0
    assert np.all(
        np.isfinite(backend.solve(KinematicState.compute(arm, near), xdot, np.zeros(3)).qdot)
    )


def test_a_joint_on_its_limit_does_not_move_and_without_limits_it_is_the_pseudoinverse() -> None:
    arm = PlanarArm([1.0, 0.8, 0.6], limits=LIMITS[:3])
    backend = WeightedLeastNormBackend()
    backend.bind(arm, 0.01)
    state = KinematicState.compute(arm, np.array([0.3, 2.5, -0.5]))  # on the upper limit
    out = backend.solve(state, np.array([0.3, 0.4]), np.array([0.0, 0.2, 0.0]))  # going out
    assert out.qdot[1] == 0.0 and np.all(np.isfinite(out.qdot))
    backend.reset()
    back = backend.solve(state, np.array([0.3, 0.4]), np.array([0.0, -0.2, 0.0]))  # coming in
    assert back.qdot[1] != 0.0
    free = PlanarArm([1.0, 0.8, 0.6])
    plain = WeightedLeastNormBackend()
    plain.bind(free, 0.01)
    s = KinematicState.compute(free, np.array([0.3, 0.5, -0.5]))
    np.testing.assert_allclose(
        plain.solve(s, np.array([0.3, 0.4]), np.zeros(3)).qdot,
        damped_least_squares(s, np.array([0.3, 0.4]), 0.0),
        rtol=1e-13,
    )


def test_in_a_run_it_keeps_joints_off_their_limits_where_the_pseudoinverse_hits_them() -> None:
    from otmm_qp.controller import Controller
    from otmm_qp.simulation.episode import Episode, Loop
    from otmm_qp.simulation.simulate import simulate
    from otmm_qp.trajectories.line import QuinticLineTrajectory
    from otmm_qp_controllers.pinv import PseudoInverseBackend

    arm = PlanarArm([1.0, 0.8, 0.6], limits=[[-3.0, 3.0], [-0.3, 1.6], [-3.0, 3.0]])
    q0 = np.array([0.2, 1.0, 0.4])
    line = QuinticLineTrajectory(arm.forward(q0), end=[0.0, 0.8], duration=2.0)
    margins = {}
    for name, backend in (("pinv", PseudoInverseBackend()), ("wln", WeightedLeastNormBackend())):
        result = simulate(
            Episode(arm, line, q0, 0.01, 2.5, Loop("clik", 10.0)), Controller(name, [], backend)
        )
        lower, upper = np.array(arm.position_limits)
        margins[name] = float(np.min(np.minimum(result.q - lower, upper - result.q)))
        np.testing.assert_allclose(arm.forward(result.q[-1]), [0.0, 0.8], atol=1e-4)
    assert margins["pinv"] < -0.3  # the pseudoinverse runs 0.41 rad past joint 2's limit
    assert margins["wln"] > 0.05  # WLN stays 0.1 rad inside it and still reaches the target


def test_bad_damping_names_the_field() -> None:
    with pytest.raises(ParameterError, match="^damping: must be a finite number >= 0"):
        WeightedLeastNormBackend(damping=-0.1)


def test_undamped_wln_diverges_when_the_weighting_makes_the_task_singular() -> None:
    """The paper's WLN has no damping: a target that needs a joint past its limit shows why."""
    from otmm_qp.controller import Controller
    from otmm_qp.simulation.episode import Episode, Loop
    from otmm_qp.simulation.simulate import simulate
    from otmm_qp.trajectories.line import QuinticLineTrajectory

    arm = PlanarArm([1.0, 0.8, 0.6], limits=[[-3.0, 3.0], [-0.3, 1.6], [-3.0, 3.0]])
    q0 = np.array([0.2, 1.0, 0.4])
    line = QuinticLineTrajectory(arm.forward(q0), end=[0.5, 0.3], duration=2.0)
    lower, upper = np.array(arm.position_limits)
    margin = {}
    for damping in (0.0, 0.05):
        backend = WeightedLeastNormBackend(damping=damping)
        result = simulate(
            Episode(arm, line, q0, 0.01, 2.5, Loop("clik", 10.0)), Controller("w", [], backend)
        )
        margin[damping] = float(np.min(np.minimum(result.q - lower, upper - result.q)))
        assert np.all(np.isfinite(result.q))
    assert margin[0.0] < -1.0  # undamped: a joint ends far past its limit
    assert margin[0.05] >= 0.0  # damped: stops at the limit, short of the target
