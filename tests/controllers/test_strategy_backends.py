"""J-PARSE, SNS and manipulability backends: the math they promise."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp.exceptions import ParameterError
from otmm_qp.robots import PlanarArm
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.state import KinematicState
from otmm_qp_controllers.jparse import JParseBackend
from otmm_qp_controllers.manipulability import (
    ManipulabilityBackend,
    manipulability,
    manipulability_gradient,
)
from otmm_qp_controllers.sns import SnsBackend, task_scaling_factor


def sns_limits(max_speed: float) -> list[dict[str, object]]:
    """``sns``'s default limits with the speed capped at ``max_speed`` [rad/s]."""
    return [{"type": "velocity", "max_speed": max_speed}, {"type": "position", "gain": 1}]


def reference_jparse(J: np.ndarray, xdot: np.ndarray, gamma: float, gain: float) -> np.ndarray:
    """Matrix form J_s⁺ (J_p J_p⁺ + K Φ) ẋ with numpy's pinv (independent of the SVD path)."""
    U, S, Vt = np.linalg.svd(J)
    k = S.size
    threshold = gamma * S.max()
    S_safe = np.maximum(S, threshold)
    J_safe = U[:, :k] @ np.diag(S_safe) @ Vt[:k]
    keep = S > threshold
    J_proj = U[:, :k][:, keep] @ np.diag(S[keep]) @ Vt[:k][keep]
    singular = ~keep
    Phi = U[:, :k][:, singular] @ np.diag(S[singular] / threshold) @ U[:, :k][:, singular].T
    return np.linalg.pinv(J_safe) @ (J_proj @ np.linalg.pinv(J_proj) @ xdot + gain * Phi @ xdot)


@settings(max_examples=40)
@given(
    st.integers(2, 6),
    st.integers(0, 3),
    st.integers(0, 2**31 - 1),
    st.sampled_from([0.0, 1e-8, 1e-3, 0.05]),
)
def test_jparse_matches_the_matrix_form(n: int, extra: int, seed: int, weak: float) -> None:
    rng = np.random.default_rng(seed)
    nv = n + extra
    U = np.linalg.qr(rng.normal(size=(n, n)))[0]
    V = np.linalg.qr(rng.normal(size=(nv, nv)))[0]
    S = np.sort(rng.uniform(0.5, 2.0, n))[::-1]
    S[-1] = weak
    J = U @ np.diag(S) @ V[:, :n].T
    state = KinematicState(np.zeros(nv), np.zeros(n), J, np.ones(n), J, U, S, V[:, :n].T.copy())
    xdot = rng.normal(size=n)
    backend = JParseBackend(gamma=0.1, singular_gain=2.0)
    qdot = backend.solve(state, xdot, np.zeros(nv)).qdot
    np.testing.assert_allclose(qdot, reference_jparse(J, xdot, 0.1, 2.0), atol=1e-9)
    # Bounded: every direction's gain ≤ max(1/σ_γ, K/σ_γ).
    assert np.linalg.norm(qdot) <= 2.0 / (0.1 * S[0]) * np.linalg.norm(xdot) + 1e-9


def test_jparse_at_an_exact_singularity_and_zero_command() -> None:
    arm = PlanarArm([1.0, 0.8])
    state = KinematicState.compute(arm, np.array([0.2, 0.0]))
    backend = JParseBackend()
    out = backend.solve(state, np.array([1.0, 1.0]), np.zeros(2)).qdot
    assert np.all(np.isfinite(out))
    assert abs(state.Vt[-1] @ out) < 1e-12  # σ = 0: no motion along v_s
    np.testing.assert_array_equal(backend.solve(state, np.zeros(2), np.zeros(2)).qdot, 0.0)


@pytest.mark.parametrize(
    ("factory", "message"),
    [
        (lambda: JParseBackend(gamma=0.0), "gamma: must be in (0, 1), got 0.0"),
        (lambda: JParseBackend(gamma=1.0), "gamma: must be in (0, 1), got 1.0"),
        (lambda: JParseBackend(singular_gain=-1.0), "singular_gain: must be a finite number >= 0"),
        (
            lambda: SnsBackend(limits=[{"type": "velocity", "max_speed": 0.0}]),
            "limits.0.max_speed: must be a finite number > 0 [rad/s]",
        ),
        (lambda: SnsBackend(rcond=1.0), "rcond: must be in [0, 1), got 1.0"),
        (lambda: ManipulabilityBackend(gain=-1.0), "gain: must be a finite number >= 0"),
        (lambda: ManipulabilityBackend(damping=float("inf")), "damping: must be a finite number"),
    ],
)
def test_bad_parameters_name_the_field(factory, message: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ParameterError) as info:
        factory()
    assert str(info.value).startswith(message)


@st.composite
def sns_cases(draw: st.DrawFn) -> tuple[PlanarArm, np.ndarray, np.ndarray, float]:
    m = draw(st.integers(2, 6))
    arm = PlanarArm(draw(st.lists(st.floats(0.3, 1.2), min_size=m, max_size=m)))
    q = np.array(draw(st.lists(st.floats(-3.0, 3.0), min_size=m, max_size=m)))
    if draw(st.booleans()):
        q[1:] = 0.0  # exactly singular
    xdot = np.array(draw(st.lists(st.floats(-3.0, 3.0), min_size=2, max_size=2)))
    return arm, q, xdot, draw(st.sampled_from([0.1, 0.5, 2.0]))


@settings(max_examples=80)
@given(sns_cases())
def test_sns_meets_bounds_exactly_and_preserves_the_task_direction(
    case: tuple[PlanarArm, np.ndarray, np.ndarray, float],
) -> None:
    arm, q, xdot, speed = case
    backend = SnsBackend(limits=sns_limits(speed))
    backend.bind(arm, 0.01)
    state = KinematicState.compute(arm, q)
    out = backend.solve(state, xdot, np.zeros(arm.nv))
    assert np.all(np.abs(out.qdot) <= speed)  # exactly: saturated joints sit on the bound
    assert 0.0 <= out.scale <= 1.0
    realised = state.jacobian @ out.qdot
    if state.sigma_min > 1e-6:  # full rank: J q̇ = s ẋ, the direction is kept
        # Rounding of the chained pseudoinverses grows with the conditioning of J W (the free
        # columns), which J's σ_min does not bound: 1.3e-8 on a 5-link arm at σ_min = 0.02 with
        # four joints saturated, 4.9e-9 on a 4-link one; 1e-7 of ‖ẋ‖ still tells a kept
        # direction from a changed one (the greedy-scale counter-example differs by 1e-2).
        tolerance = 1e-7 * (1.0 + float(np.abs(xdot).max()))
        np.testing.assert_allclose(realised, out.scale * xdot, rtol=0.0, atol=tolerance)
    if np.all(np.abs(np.linalg.pinv(state.jacobian) @ xdot) <= speed) and state.sigma_min > 1e-6:
        assert out.scale == 1.0  # nothing to saturate


def best_feasible_scale(jacobian: np.ndarray, xdot: np.ndarray, bound: float) -> float:
    """max s ∈ [0, 1] s.t. J q̇ = s ẋ, |q̇| ≤ bound: the LP the SNS scale is compared with."""
    from scipy.optimize import linprog

    m = jacobian.shape[1]
    A = np.hstack([jacobian, -xdot[:, None]])
    lp = linprog(
        np.r_[np.zeros(m), -1.0],
        A_eq=A,
        b_eq=np.zeros(jacobian.shape[0]),
        bounds=[(-bound, bound)] * m + [(0, 1)],
    )
    assert lp.status == 0
    return float(lp.x[-1])


@settings(max_examples=30)
@given(st.integers(3, 5), st.integers(0, 2**31 - 1))
def test_sns_task_scale_is_feasible_and_never_above_the_lp_optimum(m: int, seed: int) -> None:
    """On redundant arms the greedy SNS scale is realised exactly and is ≤ the best feasible one."""
    rng = np.random.default_rng(seed)
    arm = PlanarArm(list(rng.uniform(0.4, 1.2, m)))
    state = KinematicState.compute(arm, rng.uniform(-2.5, 2.5, m))
    if state.sigma_min < 1e-3:
        return
    xdot = rng.normal(size=2) * 2.0
    backend = SnsBackend(limits=sns_limits(1.0))
    backend.bind(arm, 0.01)
    out = backend.solve(state, xdot, np.zeros(m))
    optimum = best_feasible_scale(state.jacobian, xdot, 1.0)
    # The real property of every step, saturated or not: a feasible, direction-preserving
    # q̇ that realises exactly the scale it reports, and that scale is at most the optimum.
    assert np.all(np.abs(out.qdot) <= 1.0)
    np.testing.assert_allclose(state.jacobian @ out.qdot, out.scale * xdot, atol=1e-9)
    assert 0.0 <= out.scale <= optimum + 1e-9
    if optimum > 0.0:
        assert out.scale > 0.0  # greedy, but it never gives up on a feasible task
    if optimum == pytest.approx(1.0, abs=1e-12) and out.scale == 1.0:
        assert out.status in ("ok", "bounded")


def test_sns_greedy_scale_is_strictly_below_the_best_feasible_one() -> None:
    """The counter-example to "optimal": the LP finds a 2 % larger scale than greedy SNS."""
    arm = PlanarArm([1.0, 1.0, 1.0])
    backend = SnsBackend(limits=sns_limits(1.0))
    backend.bind(arm, 0.01)
    state = KinematicState.compute(arm, np.array([-1.0, -1.8, -0.2]))
    xdot = np.array([-1.0, -1.8])
    out = backend.solve(state, xdot, np.zeros(3))
    optimum = best_feasible_scale(state.jacobian, xdot, 1.0)
    assert out.status == "bounded"
    assert out.scale == pytest.approx(0.73094, abs=1e-5)
    assert optimum == pytest.approx(0.74638, abs=1e-5)
    assert out.scale < optimum - 0.01
    np.testing.assert_allclose(state.jacobian @ out.qdot, out.scale * xdot, atol=1e-12)


def test_sns_greedy_gap_over_random_redundant_cases() -> None:
    """How often and by how much the greedy scale falls short (the numbers in sns.py, docs)."""
    ratios = []
    for seed in range(300):
        rng = np.random.default_rng(seed)
        m = int(rng.integers(3, 6))
        arm = PlanarArm(list(rng.uniform(0.4, 1.2, m)))
        state = KinematicState.compute(arm, rng.uniform(-2.5, 2.5, m))
        if state.sigma_min < 1e-3:
            continue
        xdot = rng.normal(size=2) * 2.0
        backend = SnsBackend(limits=sns_limits(1.0))
        backend.bind(arm, 0.01)
        scale = backend.solve(state, xdot, np.zeros(m)).scale
        optimum = best_feasible_scale(state.jacobian, xdot, 1.0)
        assert scale <= optimum + 1e-9
        ratios.append(scale / optimum if optimum > 0.0 else 1.0)
    ratio = np.array(ratios)
    assert ratio.size == 300
    assert ratio.min() >= 0.99  # never far below (measured: 0.991) ...
    assert 1 <= np.count_nonzero(ratio < 1.0 - 1e-6) <= 5  # ... and rarely below (measured: 2)


def test_sns_uses_redundancy_before_scaling() -> None:
    """A 3-link arm: the full task needs one joint saturated; here SNS matches the LP optimum."""
    arm = PlanarArm([1.0, 1.0, 1.0])
    backend = SnsBackend(limits=sns_limits(1.0))
    backend.bind(arm, 0.01)
    state = KinematicState.compute(arm, np.array([0.3, 0.8, 0.5]))
    ok = backend.solve(state, np.array([0.0, 1.0]), np.zeros(3))
    assert ok.scale == 1.0 and ok.status == "ok"
    out = backend.solve(state, np.array([0.0, 1.2]), np.zeros(3))
    assert out.status == "bounded"
    assert out.scale == pytest.approx(0.95213735, abs=1e-7)  # linprog optimum of this case
    np.testing.assert_allclose(state.jacobian @ out.qdot, [0.0, 1.2 * out.scale], atol=1e-12)


def test_task_scaling_factor() -> None:
    s, joint = task_scaling_factor(
        np.array([2.0, -1.0]), np.zeros(2), np.array([-1.0, -1.0]), np.array([1.0, 1.0])
    )
    assert s == pytest.approx(0.5) and joint == 0


def fd_manipulability(robot, q: np.ndarray, weight: np.ndarray | None) -> np.ndarray:  # type: ignore[no-untyped-def]
    h = 1e-6
    out = np.zeros(robot.nv)
    for k in range(robot.nv):
        e = np.zeros(robot.nv)
        e[k] = 1.0
        plus = manipulability(KinematicState.compute(robot, robot.integrate(q, e, h), weight))
        minus = manipulability(KinematicState.compute(robot, robot.integrate(q, e, -h), weight))
        out[k] = (plus - minus) / (2 * h)
    return out


def test_manipulability_gradient_matches_finite_differences_and_trace_form() -> None:
    arm = PlanarArm([1.0, 0.8, 0.8, 0.6])
    q = np.array([-1.2, 1.1, 0.7, 0.4])
    state = KinematicState.compute(arm, q)
    gradient = manipulability_gradient(arm, state)
    np.testing.assert_allclose(gradient, fd_manipulability(arm, q, None), atol=1e-7)
    J = state.jacobian
    w = np.sqrt(np.linalg.det(J @ J.T))
    trace = [
        w * np.trace(np.linalg.solve(J @ J.T, arm.jacobian_derivative(q, np.eye(4)[k]) @ J.T))
        for k in range(4)
    ]
    np.testing.assert_allclose(gradient, trace, atol=1e-10)
    panda = PinocchioArm(name="panda", task="pose")
    weight = np.array([1, 1, 1, 0.2, 0.2, 0.2])
    qp = panda.configuration(np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8]))
    pstate = KinematicState.compute(panda, qp, weight)
    np.testing.assert_allclose(
        manipulability_gradient(panda, pstate), fd_manipulability(panda, qp, weight), atol=1e-6
    )


def test_manipulability_step_stays_in_the_null_space_and_raises_w() -> None:
    arm = PlanarArm([1.0, 0.8, 0.8, 0.6])
    backend = ManipulabilityBackend(gain=1.0)
    backend.bind(arm, 0.01)
    state = KinematicState.compute(arm, np.array([0.1, 0.05, 0.05, 0.05]))  # near stretch
    xdot = np.array([0.1, 0.2])
    qdot = backend.solve(state, xdot, np.zeros(4)).qdot
    np.testing.assert_allclose(state.jacobian @ qdot, xdot, atol=1e-9)
    still = KinematicState.compute(arm, state.q)
    null_only = backend.solve(still, np.zeros(2), np.zeros(4)).qdot
    after = KinematicState.compute(arm, arm.integrate(state.q, null_only, 1e-3))
    assert manipulability(after) > manipulability(still)
    two_link = PlanarArm([1.0, 0.8])  # not redundant: pure pseudoinverse
    backend.bind(two_link, 0.01)
    s2 = KinematicState.compute(two_link, np.array([0.3, 0.5]))
    np.testing.assert_allclose(
        backend.solve(s2, xdot, np.zeros(2)).qdot, np.linalg.solve(s2.jacobian, xdot)
    )


def test_jparse_as_its_authors_run_it_row_gains_and_null_space_term() -> None:
    """q̇ = J_s⁺(P + KΦ) G ẋ + (I − J_s⁺J_s) q̇_2 against a matrix form on the Panda pose task."""
    panda = PinocchioArm(name="panda", task="pose")
    home = np.zeros(7)
    backend = JParseBackend(
        gamma=0.2,
        singular_gain=2.0,
        position_gain=3.0,
        orientation_gain=0.5,
        secondary={"type": "posture", "gain": 3.0, "q_nominal": list(home), "max_speed": 0.6},
    )
    backend.bind(panda, 0.01)
    rng = np.random.default_rng(4)
    for q in (
        np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8]),
        np.array([0.0, 0.0, 0.0, -0.05, 0.0, 0.1, 0.0]),
    ):
        state = KinematicState.compute(panda, panda.configuration(q))
        xdot = rng.normal(size=6)
        G = np.diag([3.0] * 3 + [0.5] * 3)
        J = state.jacobian
        q2 = np.clip(3.0 * (home - q), -0.6, 0.6)
        U, S, Vt = np.linalg.svd(J)
        J_safe = U @ np.diag(np.maximum(S, 0.2 * S.max())) @ Vt[:6]
        N = np.eye(7) - np.linalg.pinv(J_safe) @ J_safe
        expected = reference_jparse(J, G @ xdot, 0.2, 2.0) + N @ q2
        np.testing.assert_allclose(
            backend.solve(state, xdot, np.zeros(7)).qdot, expected, atol=1e-9
        )
        # The null-space term never changes the task velocity.
        pure = backend.solve(state, np.zeros(6), np.zeros(7)).qdot
        np.testing.assert_allclose(J @ pure, 0.0, atol=1e-10)
    # Defaults keep today's J-PARSE exactly.
    plain = JParseBackend()
    plain.bind(panda, 0.01)
    state = KinematicState.compute(panda, panda.configuration(np.full(7, 0.3)))
    xdot = rng.normal(size=6)
    np.testing.assert_array_equal(
        plain.solve(state, xdot, np.zeros(7)).qdot,
        state.Vt.T @ (plain.gains(state.sigma) * (xdot @ state.U)),
    )


def test_jparse_orientation_gain_needs_a_pose_task() -> None:
    backend = JParseBackend(orientation_gain=2.0)
    with pytest.raises(ParameterError, match="^orientation_gain: applies to pose tasks only"):
        backend.bind(PlanarArm([1.0, 0.8]), 0.01)
    with pytest.raises(ParameterError, match="^position_gain: must be a finite number >= 0"):
        JParseBackend(position_gain=-1.0)


@settings(max_examples=30)
@given(st.integers(2, 5), st.integers(0, 2**31 - 1))
def test_jparse_with_secondary_is_finite_at_exact_singularities(m: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    arm = PlanarArm(list(rng.uniform(0.3, 1.2, m)))
    backend = JParseBackend(
        position_gain=2.0, secondary={"type": "posture", "gain": 2.0, "max_speed": 0.6}
    )
    backend.bind(arm, 0.01)
    q = np.r_[rng.uniform(-3.0, 3.0), np.zeros(m - 1)]  # fully stretched: σ_min = 0
    state = KinematicState.compute(arm, q)
    xdot = rng.normal(size=2)
    out = backend.solve(state, xdot, np.zeros(m)).qdot
    assert np.all(np.isfinite(out))
    # Bounded: task part ≤ K_max/σ_γ · ‖Gẋ‖ and the projected secondary ≤ its cap.
    gamma_sigma = 0.1 * state.sigma[0]
    assert np.linalg.norm(out) <= 2.0 * np.linalg.norm(xdot) / gamma_sigma + 0.6 * np.sqrt(m) + 1e-9
    # The null-space term adds no task velocity.
    pure = backend.solve(state, np.zeros(2), np.zeros(m)).qdot
    np.testing.assert_allclose(state.jacobian @ pure, 0.0, atol=1e-10)
