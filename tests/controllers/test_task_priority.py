"""Singularity-robust task priority (Chiaverini 1997) and its secondary tasks."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp.exceptions import ConfigError, DimensionError, ParameterError
from otmm_qp.robots import PlanarArm
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.state import KinematicState
from otmm_qp_controllers.secondary_tasks import (
    JointLimitTask,
    PostureTask,
    limit_distance_gradient,
    secondary_task_from,
)
from otmm_qp_controllers.task_priority import TaskPriorityBackend, sigma_damping


def synthetic_state(
    n: int, nv: int, seed: int, weak: float
) -> tuple[PlanarArm, KinematicState, np.random.Generator]:
    """A state whose weighted Jacobian has a chosen smallest singular value."""
    rng = np.random.default_rng(seed)
    U = np.linalg.qr(rng.normal(size=(n, n)))[0]
    V = np.linalg.qr(rng.normal(size=(nv, nv)))[0]
    S = np.sort(rng.uniform(0.5, 2.0, n))[::-1]
    S[-1] = weak
    J = U @ np.diag(S) @ V[:, :n].T
    q = rng.uniform(-1.0, 1.0, nv)
    state = KinematicState(q, np.zeros(n), J, np.ones(n), J, U, S, V[:, :n].T.copy())
    return PlanarArm([1.0] * nv), state, rng


@settings(max_examples=60)
@given(st.integers(2, 4), st.integers(1, 3), st.integers(0, 2**31 - 1))
def test_secondary_unchanged_when_the_primary_is_satisfiable_and_non_singular(
    n: int, extra: int, seed: int
) -> None:
    nv = n + extra
    arm, state, rng = synthetic_state(n, nv, seed, weak=0.3)  # σ_min 0.3 > ε: λ = 0
    for projector in ("damped", "exact"):
        backend = TaskPriorityBackend(
            {"type": "posture", "gain": 2.0, "q_nominal": list(rng.normal(size=nv))},
            projector=projector,
        )
        backend.bind(arm, 0.01)
        q2 = backend.secondary.joint_velocity(arm, state)
        xdot = rng.normal(size=n)
        out = backend.solve(state, xdot, np.zeros(nv))
        J = state.jacobian
        N = np.eye(nv) - np.linalg.pinv(J) @ J
        np.testing.assert_allclose(J @ out.qdot, xdot, atol=1e-9)  # primary met exactly
        np.testing.assert_allclose(N @ out.qdot, N @ q2, atol=1e-9)  # secondary's part kept
        compatible = backend.solve(state, J @ q2, np.zeros(nv)).qdot
        np.testing.assert_allclose(compatible, q2, atol=1e-9)  # a compatible one: untouched
        assert out.damping == 0.0


@settings(max_examples=60)
@given(
    st.integers(2, 4),
    st.integers(0, 3),
    st.integers(0, 2**31 - 1),
    st.sampled_from([0.0, 1e-12, 1e-4, 0.02]),
)
def test_finite_and_bounded_at_singular_jacobians(
    n: int, extra: int, seed: int, weak: float
) -> None:
    nv = n + extra
    arm, state, rng = synthetic_state(n, nv, seed, weak)
    lam = 0.05
    for projector in ("damped", "exact"):
        backend = TaskPriorityBackend(
            {"type": "posture", "gain": 1.0}, max_damping=lam, projector=projector
        )
        backend.bind(arm, 0.01)
        xdot = rng.normal(size=n)
        out = backend.solve(state, xdot, np.zeros(nv))
        q2 = backend.secondary.joint_velocity(arm, state)
        assert np.all(np.isfinite(out.qdot))
        mu = sigma_damping(weak, lam, 0.05)
        # ‖J^{#λ}‖ ≤ 1/(2λ) ... and ‖N‖ ≤ 1, with λ² = mu.
        limit = (
            np.linalg.norm(xdot) / (2.0 * np.sqrt(mu)) if mu > 0 else np.linalg.norm(xdot) / weak
        )
        assert np.linalg.norm(out.qdot) <= limit + np.linalg.norm(q2) + 1e-9
    if weak == 0.0:
        # Along the exactly singular direction the damped projector passes the secondary in full.
        damped = TaskPriorityBackend({"type": "posture", "gain": 1.0}, max_damping=lam)
        damped.bind(arm, 0.01)
        q2 = damped.secondary.joint_velocity(arm, state)
        v = state.Vt[-1]
        assert v @ damped.solve(state, np.zeros(n), np.zeros(nv)).qdot == pytest.approx(
            v @ q2, abs=1e-12
        )


def test_on_a_real_arm_the_null_space_motion_moves_toward_the_posture() -> None:
    panda = PinocchioArm(name="panda", task="position")
    backend = TaskPriorityBackend({"type": "posture", "gain": 1.0})
    backend.bind(panda, 0.01)
    q = panda.configuration(np.array([0.5, -0.3, 0.4, -2.2, 0.3, 2.0, 0.8]))
    state = KinematicState.compute(panda, q)
    qdot = backend.solve(state, np.zeros(3), np.zeros(7)).qdot
    np.testing.assert_allclose(state.jacobian @ qdot, 0.0, atol=1e-10)
    lower, upper = panda.position_limits
    middle = 0.5 * (lower + upper)
    theta = panda.joint_coordinates(q)
    after = panda.joint_coordinates(panda.integrate(q, qdot, 0.01))
    assert np.linalg.norm(after - middle) < np.linalg.norm(theta - middle)


def test_joint_limit_task_is_the_negative_gradient() -> None:
    lower, upper = np.array([-1.0, -2.0, -np.inf]), np.array([1.0, 0.0, np.inf])
    theta = np.array([0.5, -1.5, 3.0])
    h = 1e-6

    def cost(t: np.ndarray) -> float:
        low, high = lower[:2], upper[:2]
        return float(np.sum(((t[:2] - 0.5 * (low + high)) / (high - low)) ** 2) / (2 * 2))

    fd = [(cost(theta + h * e) - cost(theta - h * e)) / (2 * h) for e in np.eye(3)]
    np.testing.assert_allclose(limit_distance_gradient(theta, lower, upper), fd, atol=1e-8)
    arm = PlanarArm([1.0, 1.0, 1.0])
    task = JointLimitTask(gain=3.0)
    state = KinematicState.compute(arm, np.zeros(3))
    assert task.joint_velocity(arm, state).shape == (3,)


@pytest.mark.parametrize(
    ("spec", "error", "message"),
    [
        ({"type": "nope"}, ConfigError, "secondary.type: unknown secondary task 'nope'; available"),
        ({}, ConfigError, "secondary.type: unknown secondary task None"),
        ({"type": "posture", "gian": 1.0}, ConfigError, "secondary.gian: unknown parameter"),
        ({"type": "posture", "gain": -1.0}, ParameterError, "secondary.gain: must be a finite"),
        (
            {"type": "posture", "max_speed": 0.0},
            ParameterError,
            "secondary.max_speed: must be a finite number > 0",
        ),
        ({"type": "posture", "q_nominal": ["a"]}, ParameterError, "secondary.q_nominal"),
        (
            {"type": "joint_limits", "gain": float("nan")},
            ParameterError,
            "secondary.gain: must be a",
        ),
        ("posture", ConfigError, "secondary: must be {type: NAME, ...}"),
    ],
)
def test_bad_secondary_blocks_name_the_field(
    spec: object, error: type[Exception], message: str
) -> None:
    with pytest.raises(error) as info:
        secondary_task_from(spec)  # type: ignore[arg-type]
    assert str(info.value).startswith(message)


def test_bad_parameters_name_the_field() -> None:
    with pytest.raises(ParameterError, match="^max_damping: must be a finite number"):
        TaskPriorityBackend(max_damping=float("inf"))
    with pytest.raises(ParameterError, match="^sigma_threshold: must be a finite number > 0"):
        TaskPriorityBackend(sigma_threshold=0.0)
    with pytest.raises(ParameterError, match="^projector: must be 'damped' or 'exact'"):
        TaskPriorityBackend(projector="soft")  # type: ignore[arg-type]
    backend = TaskPriorityBackend({"type": "posture", "q_nominal": [0.0, 0.0]})
    with pytest.raises(DimensionError, match="secondary.q_nominal: expected shape"):
        backend.bind(PlanarArm([1.0, 1.0, 1.0]), 0.01)
    assert isinstance(TaskPriorityBackend().secondary, PostureTask)
