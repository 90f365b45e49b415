"""OTMM (paper eq. 8) invariants, as property tests over random arms and configurations."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from otmm_qp.exceptions import ConfigError, ParameterError
from otmm_qp.filters import OtmmFilter
from otmm_qp.filters import p_functions as pf
from otmm_qp.robots import PlanarArm
from otmm_qp.state import KinematicState

P_NAMES = ["linear", "sqrt", "cbrt"]


@st.composite
def arm_states(draw: st.DrawFn) -> tuple[KinematicState, np.ndarray]:
    m = draw(st.integers(2, 5))
    lengths = draw(st.lists(st.floats(0.2, 1.5), min_size=m, max_size=m))
    arm = PlanarArm(lengths)
    q = np.array(draw(st.lists(st.floats(-np.pi, np.pi), min_size=m, max_size=m)))
    if draw(st.booleans()):  # near or exactly at the stretched singularity
        q[1:] = draw(st.sampled_from([0.0, 1e-9, 1e-4, 1e-2]))
    xdot = np.array(draw(st.lists(st.floats(-2, 2), min_size=2, max_size=2)))
    return KinematicState.compute(arm, q), xdot


@given(arm_states(), st.sampled_from(P_NAMES), st.floats(1e-3, 0.5))
def test_component_along_u_s_scaled_by_one_minus_p_rest_untouched(
    case: tuple[KinematicState, np.ndarray], p_name: str, sigma_s: float
) -> None:
    state, xdot = case
    otmm = OtmmFilter(sigma_s=sigma_s, p=p_name)
    modified, report = otmm.apply(state, xdot)
    u_s = state.U[:, -1]
    sigma_min = state.sigma_min
    if sigma_min > sigma_s:
        np.testing.assert_array_equal(modified, xdot)  # unchanged above σ_S
        assert not report.active
        return
    p = getattr(pf, p_name)(sigma_min, sigma_s)
    assert report.p == pytest.approx(p)
    assert u_s @ modified == pytest.approx((1 - p) * (u_s @ xdot), abs=1e-12)
    orthogonal = xdot - (u_s @ xdot) * u_s
    np.testing.assert_allclose(modified - (u_s @ modified) * u_s, orthogonal, atol=1e-12)
    assert np.linalg.norm(modified) <= np.linalg.norm(xdot) + 1e-12  # never grows


@given(arm_states(), st.sampled_from(P_NAMES))
def test_continuous_at_sigma_s(case: tuple[KinematicState, np.ndarray], p_name: str) -> None:
    state, xdot = case
    sigma_min = state.sigma_min
    if sigma_min <= 0.0:
        return
    at = OtmmFilter(sigma_s=sigma_min, p=p_name).apply(state, xdot).xdot  # σ_min = σ_S: p = 0
    just_above = OtmmFilter(sigma_s=sigma_min * (1 - 1e-9), p=p_name).apply(state, xdot).xdot
    np.testing.assert_allclose(at, xdot, atol=1e-12)
    np.testing.assert_allclose(just_above, xdot, atol=1e-12)


def test_exactly_singular_removes_the_unachievable_component() -> None:
    """Paper Fig. 7: at q = [0, 0] only the achievable (y) component survives."""
    state = KinematicState.compute(PlanarArm([1.0, 0.8]), np.zeros(2))
    for p_name in P_NAMES:
        modified = OtmmFilter(0.05, p_name).apply(state, np.array([-0.3, 0.7])).xdot
        np.testing.assert_allclose(modified, [0.0, 0.7], atol=1e-15)


def test_p_functions_endpoints_and_order() -> None:
    for name in P_NAMES:
        function = getattr(pf, name)
        assert function(0.0, 0.05) == 1.0
        assert function(0.05, 0.05) == 0.0
    s = 0.01
    # Less suppression with a lower root: linear > sqrt > cbrt at the same σ.
    assert pf.linear(s, 0.05) > pf.sqrt(s, 0.05) > pf.cbrt(s, 0.05)
    assert pf.power(s, 0.05, a=0.5) == pytest.approx(pf.sqrt(s, 0.05))


def test_singular_direction_gain_bounded_only_for_linear() -> None:
    """(1−p)/σ along u_s: ≤ 1/σ_S for linear, unbounded as σ → 0 for sqrt and cbrt."""
    sigma_s = 0.05
    for sigma in [1e-2, 1e-4, 1e-8]:
        assert (1 - pf.linear(sigma, sigma_s)) / sigma == pytest.approx(1 / sigma_s)
    assert (1 - pf.sqrt(1e-8, sigma_s)) / 1e-8 > 1e3 / sigma_s
    assert (1 - pf.cbrt(1e-8, sigma_s)) / 1e-8 > 1e4 / sigma_s


def test_parameter_errors() -> None:
    with pytest.raises(ParameterError, match="sigma_s: must be a finite number > 0"):
        OtmmFilter(sigma_s=0.0)
    with pytest.raises(
        ConfigError,
        match="unknown p-function 'quartic'; available: bounded, cbrt, linear, power, sqrt",
    ):
        OtmmFilter(p="quartic")
    with pytest.raises(ConfigError, match="p_params.b: unknown parameter; allowed: a"):
        OtmmFilter(p="power", p_params={"b": 2})
    with pytest.raises(ParameterError, match="p_params.a: must be a finite number > 0"):
        OtmmFilter(p="power", p_params={"a": -1})
