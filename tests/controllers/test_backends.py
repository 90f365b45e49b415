"""Built-in backends: exact inverse away from singularity, DLS limits, finite at singularity."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from otmm_qp.exceptions import ConfigError, ParameterError
from otmm_qp.robots import PlanarArm
from otmm_qp.state import KinematicState
from otmm_qp_controllers.dls_adaptive import AdaptiveDampedLeastSquaresBackend
from tests.conftest import make_backend

ALL = ["pinv", "dls", "dls_adaptive", "dls_sigma", "sdls"]
PARAMS: dict[str, dict[str, object]] = {"dls_adaptive": {"sigma_threshold": 0.05}}


def solve(
    name: str, state: KinematicState, xdot: np.ndarray, dt: float = 0.02, **params: object
) -> np.ndarray:
    backend = make_backend(name, **{**PARAMS.get(name, {}), **params})
    backend.bind(PlanarArm([1.0] * state.jacobian.shape[1]), dt)
    return backend.solve(state, xdot, np.zeros(state.jacobian.shape[1])).qdot


@given(seed=st.integers(0, 10_000), m=st.integers(2, 5))
def test_pinv_is_the_exact_inverse_away_from_singularity(seed: int, m: int) -> None:
    rng = np.random.default_rng(seed)
    arm = PlanarArm(rng.uniform(0.3, 1.2, m))
    q = rng.uniform(-np.pi, np.pi, m)
    state = KinematicState.compute(arm, q)
    if state.sigma_min < 0.1:
        return
    xdot = rng.normal(size=2)
    qdot = solve("pinv", state, xdot)
    J = state.jacobian
    expected = np.linalg.solve(J, xdot) if m == 2 else J.T @ np.linalg.solve(J @ J.T, xdot)
    np.testing.assert_allclose(qdot, expected, atol=1e-9)
    # Damping vanishes far from the singularity for the adaptive and σ-driven variants.
    np.testing.assert_allclose(solve("dls_adaptive", state, xdot), expected, atol=1e-9)
    np.testing.assert_allclose(solve("dls_sigma", state, xdot), expected, atol=1e-9)


def test_dls_tends_to_pinv_as_damping_vanishes() -> None:
    state = KinematicState.compute(PlanarArm([1.0, 0.8, 0.5]), np.array([0.3, 0.4, -0.2]))
    xdot = np.array([0.2, -0.1])
    exact = solve("pinv", state, xdot)
    gaps = [
        np.linalg.norm(solve("dls", state, xdot, damping=lam) - exact)
        for lam in [1e-1, 1e-2, 1e-3, 1e-4]
    ]
    assert all(a > b for a, b in zip(gaps, gaps[1:], strict=False))
    assert gaps[-1] < 1e-6
    J = state.jacobian
    lam = 0.1
    closed_form = J.T @ np.linalg.solve(J @ J.T + lam**2 * np.eye(2), xdot)
    np.testing.assert_allclose(solve("dls", state, xdot, damping=lam), closed_form, atol=1e-12)


def test_adaptive_damping_follows_nakamura_hanafusa() -> None:
    arm = PlanarArm([1.0, 0.8])
    state = KinematicState.compute(arm, np.array([0.1, 0.01]))  # near stretched
    backend = AdaptiveDampedLeastSquaresBackend(alpha=0.003, w0=0.04)
    w = float(np.prod(state.sigma))
    assert w == pytest.approx(abs(np.linalg.det(state.jacobian)))
    assert backend.damping_for(state) == pytest.approx(0.003 * (1 - w / 0.04) ** 2)
    J = state.jacobian
    k = backend.damping_for(state)
    backend.bind(arm, 0.02)
    xdot = np.array([0.3, 0.1])
    expected = J.T @ np.linalg.solve(J @ J.T + k * np.eye(2), xdot)
    np.testing.assert_allclose(backend.solve(state, xdot, np.zeros(2)).qdot, expected, atol=1e-12)


@pytest.mark.parametrize("name", ALL)
@pytest.mark.parametrize("q2", [0.0, 1e-12, 1e-6])
def test_every_backend_is_finite_at_and_near_the_singularity(name: str, q2: float) -> None:
    state = KinematicState.compute(PlanarArm([1.0, 0.8]), np.array([0.2, q2]))
    qdot = solve(name, state, np.array([1.0, 1.0]))
    assert np.all(np.isfinite(qdot))


def test_truncated_pinv_uses_only_the_achievable_row_at_exact_singularity() -> None:
    state = KinematicState.compute(PlanarArm([1.0, 0.8]), np.zeros(2))
    qdot = solve("pinv", state, np.array([-0.5, 0.7]))
    np.testing.assert_allclose(state.jacobian @ qdot, [0.0, 0.7], atol=1e-12)


def test_sdls_clamps_each_step_to_gamma_max() -> None:
    state = KinematicState.compute(PlanarArm([1.0, 0.8]), np.array([0.2, 1e-6]))
    dt, gamma = 0.02, 0.1
    qdot = solve("sdls", state, np.array([5.0, 5.0]), dt=dt, gamma_max=gamma)
    assert np.max(np.abs(qdot)) * dt <= gamma + 1e-12


def test_bad_parameters() -> None:
    with pytest.raises(ParameterError, match="damping: must be a finite number >= 0"):
        make_backend("dls", damping=-1.0)
    with pytest.raises(ConfigError, match="w0: give exactly one of w0 or sigma_threshold"):
        make_backend("dls_adaptive")
    with pytest.raises(ParameterError, match="epsilon: must be a finite number > 0"):
        make_backend("dls_sigma", epsilon=0.0)
    with pytest.raises(ParameterError, match=r"rcond: must be in \[0, 1\)"):
        make_backend("pinv", rcond=2.0)
