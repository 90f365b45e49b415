"""Direction-aware OTMM: suppresses the singular component only while it shrinks σ_min."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from otmm_qp.exceptions import ConfigError
from otmm_qp.filters.direction_aware_otmm import DirectionAwareOtmmFilter
from otmm_qp.robots import PlanarArm
from otmm_qp.singularity import sigma_min_rate
from otmm_qp.state import KinematicState
from otmm_qp_controllers.pinv import PseudoInverseBackend

ARM = PlanarArm([1.0, 0.8])
DT = 0.02


def bound_filter(**params: object) -> DirectionAwareOtmmFilter:
    f = DirectionAwareOtmmFilter(**params)  # type: ignore[arg-type]
    f.bind(ARM, DT)
    return f


def sigma_after(state: KinematicState, xdot: np.ndarray, h: float = 1e-7) -> float:
    """σ_min after a tiny step of the pseudoinverse motion (finite-difference reference)."""
    qdot = PseudoInverseBackend().solve(state, xdot, np.zeros(2)).qdot
    return KinematicState.compute(ARM, ARM.integrate(state.q, qdot, h)).sigma_min


def test_leaving_is_only_capped_and_approaching_is_suppressed() -> None:
    state = KinematicState.compute(ARM, np.array([0.3, 0.02]))  # near full stretch
    sigma, u_s = state.sigma_min, state.U[:, -1]
    assert sigma < 0.05
    # Which sign of u_s raises σ_min, judged by finite differences, not by the filter's r.
    raising = u_s if sigma_after(state, u_s) > sigma else -u_s
    f = bound_filter()
    out_leave = f.apply(state, 0.1 * raising)
    assert not f.approaching
    assert out_leave.report.p == pytest.approx(max(0.0, 1.0 - f.max_gain * sigma))
    f.reset()
    out_approach = f.apply(state, -0.1 * raising)
    assert f.approaching
    assert out_approach.report.p > out_leave.report.p
    # The suppressed command still moves σ_min the same way, just less.
    assert sigma_after(state, out_approach.xdot) <= sigma


def test_hysteresis_keeps_the_state_inside_the_band() -> None:
    state = KinematicState.compute(ARM, np.array([0.3, 0.02]))
    u_s = state.U[:, -1]
    r = sigma_min_rate(ARM, state, state.Vt[-1])
    f = bound_filter(approach_rate=-1.0, leave_rate=1.0)
    sign = np.sign(r)
    f.apply(state, 0.1 * sign * u_s)  # λ ≫ 1: leaving
    assert not f.approaching
    gain = min(1.0 / state.sigma_min, f.max_gain)
    tiny = 0.5 * state.sigma_min / (abs(r) * gain)  # |λ| = 0.5 < 1: inside the band
    f.apply(state, -tiny * sign * u_s)
    assert not f.approaching and abs(f.last_rate) == pytest.approx(0.5)
    f.apply(state, -3 * tiny * sign * u_s)  # λ = −1.5: approaching
    assert f.approaching
    f.apply(state, tiny * sign * u_s)  # λ = +0.5: stays approaching
    assert f.approaching


@st.composite
def near_stretch(draw: st.DrawFn) -> tuple[KinematicState, np.ndarray]:
    q1 = draw(st.floats(-np.pi, np.pi))
    q2 = draw(st.sampled_from([0.0, 1e-12, 1e-6, 1e-4, 1e-3, 0.01, 0.03, -0.02]))
    xdot = np.array(draw(st.lists(st.floats(-2, 2), min_size=2, max_size=2)))
    return KinematicState.compute(ARM, np.array([q1, q2])), xdot


@given(near_stretch(), st.booleans())
def test_only_u_s_is_touched_and_gain_is_capped(
    case: tuple[KinematicState, np.ndarray], bound: bool
) -> None:
    state, xdot = case
    f = bound_filter() if bound else DirectionAwareOtmmFilter()
    out = f.apply(state, xdot)
    assert np.all(np.isfinite(out.xdot))
    u_s, v_s = state.U[:, -1], state.Vt[-1]
    np.testing.assert_allclose(
        out.xdot - (u_s @ out.xdot) * u_s, xdot - (u_s @ xdot) * u_s, atol=1e-12
    )
    assert 0.0 <= out.report.p <= 1.0
    qdot = PseudoInverseBackend().solve(state, out.xdot, np.zeros(2)).qdot
    leak = 1e-12 * (1.0 + float(np.abs(qdot).sum()))
    assert abs(v_s @ qdot) <= f.max_gain * abs(u_s @ xdot) * (1 + 1e-9) + leak
    if state.sigma_min == 0.0:
        assert out.report.p == 1.0 or u_s @ xdot == 0.0


def test_zero_command_and_exact_singularity_are_normal_inputs() -> None:
    f = bound_filter()
    singular = KinematicState.compute(ARM, np.array([0.4, 0.0]))
    assert singular.sigma_min < 1e-15
    zero = f.apply(singular, np.zeros(2))
    np.testing.assert_array_equal(zero.xdot, 0.0)
    out = f.apply(singular, np.array([1.0, -0.5]))
    assert np.all(np.isfinite(out.xdot)) and out.report.p == pytest.approx(1.0)
    regular = KinematicState.compute(ARM, np.array([0.4, 1.5]))
    xdot = np.array([0.3, 0.2])
    assert f.apply(regular, xdot).xdot is xdot


def test_structurally_singular_arm_removes_the_missing_direction() -> None:
    arm = PlanarArm([1.0])
    f = DirectionAwareOtmmFilter()
    f.bind(arm, DT)
    state = KinematicState.compute(arm, np.array([0.3]))
    out = f.apply(state, np.array([1.0, 1.0]))
    np.testing.assert_allclose(state.jacobian[:, 0] @ out.xdot, state.jacobian[:, 0] @ [1.0, 1.0])
    assert out.report.p == 1.0


@pytest.mark.parametrize(
    ("params", "message"),
    [
        ({"sigma_s": 0.0}, "sigma_s: must be a finite number > 0, got 0.0"),
        ({"max_gain": -1.0}, "max_gain: must be a finite number > 0 or None, got -1.0"),
        ({"max_gain": 5.0}, "max_gain: must be >= 1/sigma_s = 20"),
        ({"approach_rate": float("nan")}, "approach_rate: must be a finite number [1/s], got nan"),
        (
            {"approach_rate": 1.0, "leave_rate": 1.0},
            "leave_rate: must be a finite number > approach_rate (1.0), got 1.0",
        ),
        ({"sigma_decay": 0.0}, "sigma_decay: must be in (0, 1], got 0.0"),
        ({"sigma_decay": 1.5}, "sigma_decay: must be in (0, 1], got 1.5"),
        ({"taper_sigma": 0.1}, "taper_sigma: must be in [0, sigma_s = 0.05], got 0.1"),
        ({"p": "nope"}, "p: unknown p-function 'nope'"),
    ],
)
def test_bad_parameters_name_the_field(params: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError) as info:
        DirectionAwareOtmmFilter(**params)  # type: ignore[arg-type]
    assert str(info.value).startswith(message)
