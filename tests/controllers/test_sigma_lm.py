"""sigma_lm, otmm-qp's own strategy: λ² = w̄_N + λ_σ²(σ_min) + min(w_E‖τẋ‖², λ_e,max²)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp.exceptions import ParameterError
from otmm_qp.robots import PlanarArm
from otmm_qp.state import KinematicState
from otmm_qp_controllers.damping import damped_least_squares
from otmm_qp_controllers.sigma_lm import SigmaLevenbergMarquardtBackend
from otmm_qp_controllers.task_priority import sigma_damping


@settings(max_examples=60)
@given(
    st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3),
    st.lists(st.floats(-2.0, 2.0), min_size=2, max_size=2),
    st.booleans(),
    st.sampled_from([None, 0.05]),
)
def test_damping_is_the_sum_of_the_two_terms_and_the_step_is_dls(
    q: list[float], command: list[float], singular: bool, cap: float | None
) -> None:
    arm = PlanarArm([1.0, 0.8, 0.5])
    backend = SigmaLevenbergMarquardtBackend(error_weight=10.0, max_error_damping=cap)
    backend.bind(arm, 0.02)
    angles = np.array(q)
    if singular:
        angles[1:] = 0.0
    state = KinematicState.compute(arm, angles)
    xdot = np.array(command)
    e = 0.02 * xdot
    error_part = 10.0 * float(e @ e)
    if cap is not None:
        error_part = min(error_part, cap**2)
    mu = sigma_damping(state.sigma_min, 0.05, 0.05) + error_part
    assert backend.damping_for(state, xdot) == pytest.approx(mu, rel=1e-12, abs=1e-300)
    out = backend.solve(state, xdot, np.zeros(3))
    assert np.all(np.isfinite(out.qdot))
    np.testing.assert_allclose(
        out.qdot, damped_least_squares(state, xdot, mu), rtol=1e-12, atol=1e-12
    )
    # Bounded at every state: each gain σ/(σ² + μ) ≤ 1/(2√μ), so ‖q̇‖ ≤ ‖ẋ‖/(2√μ).
    if mu > 0.0:
        assert np.linalg.norm(out.qdot) <= np.linalg.norm(xdot) / (2.0 * np.sqrt(mu)) + 1e-9


def test_on_target_and_away_from_singularities_it_is_the_pseudoinverse() -> None:
    arm = PlanarArm([1.0, 0.8])
    backend = SigmaLevenbergMarquardtBackend()
    backend.bind(arm, 0.02)
    state = KinematicState.compute(arm, np.array([0.3, 1.2]))  # σ_min well above 0.05
    assert backend.damping_for(state, np.zeros(2)) == 0.0
    xdot = np.array([1e-6, -2e-6])
    np.testing.assert_allclose(
        backend.solve(state, xdot, np.zeros(2)).qdot,
        np.linalg.solve(state.jacobian, xdot),
        rtol=1e-9,
    )
    # At an exact singularity with zero command: zero motion, λ = λ_max.
    stretched = KinematicState.compute(arm, np.array([0.3, 0.0]))
    out = backend.solve(stretched, np.zeros(2), np.zeros(2))
    np.testing.assert_array_equal(out.qdot, 0.0)
    assert out.damping == pytest.approx(0.05)


@pytest.mark.parametrize(
    ("params", "message"),
    [
        ({"error_weight": -1.0}, "error_weight: must be a finite number >= 0"),
        ({"max_error_damping": 0.0}, "max_error_damping: must be a finite number > 0"),
        ({"max_damping": float("nan")}, "max_damping: must be a finite number"),
        ({"sigma_threshold": -1.0}, "sigma_threshold: must be a finite number > 0"),
        ({"lambda_sq_floor": -1.0}, "lambda_sq_floor: must be a finite number >= 0"),
        ({"error_horizon": 0.0}, "error_horizon: must be a finite number > 0"),
    ],
)
def test_bad_parameters_name_the_field(params: dict[str, object], message: str) -> None:
    with pytest.raises(ParameterError) as info:
        SigmaLevenbergMarquardtBackend(**params)  # type: ignore[arg-type]
    assert str(info.value).startswith(message)
