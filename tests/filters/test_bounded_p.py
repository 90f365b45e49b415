"""Bounded-gain p (issue 11): the joint speed OTMM leaves along v_s is at most G·|u_sᵀẋ|."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from otmm_qp.exceptions import ConfigError, ParameterError
from otmm_qp.filters import OtmmFilter
from otmm_qp.filters import p_functions as pf
from otmm_qp.state import KinematicState
from otmm_qp_controllers.pinv import PseudoInverseBackend


def state_from_svd(U: np.ndarray, sigma: np.ndarray, V: np.ndarray) -> KinematicState:
    """A KinematicState of J = U diag(σ) Vᵀ (no robot needed: filters see only the SVD)."""
    n, nv = U.shape[0], V.shape[0]
    k = min(n, nv)
    J = U[:, :k] @ np.diag(sigma) @ V[:, :k].T
    return KinematicState(
        np.zeros(nv), np.zeros(n), J, np.ones(n), J, U[:, :k], sigma.copy(), V[:, :k].T.copy()
    )


@st.composite
def singular_cases(draw: st.DrawFn) -> tuple[KinematicState, np.ndarray, float]:
    n = draw(st.integers(2, 6))
    nv = draw(st.integers(n, 8))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    U = np.linalg.qr(rng.normal(size=(n, n)))[0]
    V = np.linalg.qr(rng.normal(size=(nv, nv)))[0]
    sigma = np.sort(rng.uniform(0.2, 3.0, n))[::-1]
    sigma_min = draw(st.sampled_from([0.0, 1e-300, 1e-12, 1e-6, 1e-3, 0.01, 0.03, 0.0499]))
    sigma[-1] = sigma_min
    xdot = rng.normal(size=n) * draw(st.sampled_from([0.0, 1e-9, 1.0, 100.0]))
    gain = draw(st.sampled_from([20.0, 40.0, 100.0, 1e4]))
    return state_from_svd(U, sigma, V), xdot, gain


@given(singular_cases(), st.sampled_from(["linear", "sqrt", "cbrt"]))
def test_joint_speed_along_v_s_is_bounded_by_gain(
    case: tuple[KinematicState, np.ndarray, float], base: str
) -> None:
    state, xdot, gain = case
    otmm = OtmmFilter(sigma_s=0.05, p="bounded", p_params={"max_gain": gain, "base": base})
    modified = otmm.apply(state, xdot).xdot
    qdot = PseudoInverseBackend().solve(state, modified, np.zeros(state.Vt.shape[1])).qdot
    assert np.all(np.isfinite(qdot))
    along = abs(float(state.Vt[-1] @ qdot))
    command = abs(float(state.U[:, -1] @ xdot))
    # Rounding in the orthonormal factors leaks ~1e-16 of the other directions into v_s.
    leak = 1e-12 * (1.0 + float(np.abs(qdot).sum()))
    assert along <= gain * command * (1 + 1e-9) + leak
    if state.sigma_min == 0.0:
        assert along <= leak
    # Away from u_s the command passes untouched: the other directions are inverted exactly.
    rest = modified - (state.U[:, -1] @ modified) * state.U[:, -1]
    np.testing.assert_allclose(rest, xdot - (state.U[:, -1] @ xdot) * state.U[:, -1], atol=1e-12)


@pytest.mark.parametrize("base", ["linear", "sqrt", "cbrt"])
def test_bounded_p_is_a_p_function(base: str) -> None:
    """p(0) = 1, p(σ_S) = 0, monotone non-increasing, and never below the base p."""
    sigma_s = 0.05
    grid = np.linspace(0.0, sigma_s, 401)
    values = np.array([pf.bounded(s, sigma_s, base=base) for s in grid])
    assert values[0] == 1.0 and values[-1] == 0.0
    assert np.all(np.diff(values) <= 1e-15)
    base_values = np.array([getattr(pf, base)(s, sigma_s) for s in grid])
    assert np.all(values >= base_values)
    gains = (1.0 - values[1:]) / grid[1:]
    assert gains.max() <= 2.0 / sigma_s * (1 + 1e-12)  # default G = 2/σ_S


def test_default_gain_keeps_cbrt_away_from_the_singularity() -> None:
    sigma_s = 0.05
    # 1 − G·s ≤ p_cbrt(s) for s ≥ s*, where the cap stops acting: the base shape is kept there.
    for s in [0.02, 0.03, 0.04]:
        assert pf.bounded(s, sigma_s) == pytest.approx(pf.cbrt(s, sigma_s))
    assert pf.bounded(1e-4, sigma_s) == pytest.approx(1.0 - 40.0 * 1e-4)


@pytest.mark.parametrize(
    ("params", "message"),
    [
        ({"max_gain": 0.0}, "p_params.max_gain: must be a finite number > 0 or None, got 0.0"),
        ({"max_gain": -3.0}, "p_params.max_gain: must be a finite number > 0 or None, got -3.0"),
        (
            {"max_gain": float("nan")},
            "p_params.max_gain: must be a finite number > 0 or None, got n",
        ),
        ({"max_gain": 10.0}, "p_params.max_gain: must be >= 1/sigma_s = 20 so p is continuous"),
        (
            {"base": "bounded"},
            "p_params.base: must be one of 'linear', 'sqrt', 'cbrt', 'power', got",
        ),
        ({"base": "power", "a": 0.0}, "p_params.a: must be a finite number > 0, got 0.0"),
    ],
)
def test_bad_parameters_name_the_field(params: dict[str, object], message: str) -> None:
    with pytest.raises(ParameterError) as info:
        OtmmFilter(sigma_s=0.05, p="bounded", p_params=params)
    assert str(info.value).startswith(message)


def test_unknown_parameter_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match="p_params.gain: unknown parameter"):
        OtmmFilter(sigma_s=0.05, p="bounded", p_params={"gain": 40.0})
