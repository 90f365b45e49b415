"""Error-dependent damping (Sugihara 2011): λ² = eᵀW_E e + w̄_N, and what follows from it."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp import registry
from otmm_qp.exceptions import DimensionError, ParameterError
from otmm_qp.robots import PlanarArm
from otmm_qp.state import KinematicState
from otmm_qp_controllers.damping import damped_least_squares
from otmm_qp_controllers.dls_error import ErrorDampedLeastSquaresBackend


def bound(backend: ErrorDampedLeastSquaresBackend, m: int = 3, dt: float = 0.02) -> PlanarArm:
    arm = PlanarArm([1.0] * m)
    backend.bind(arm, dt)
    return arm


@settings(max_examples=40)
@given(
    st.lists(st.floats(-3.0, 3.0), min_size=2, max_size=2),
    st.floats(0.0, 1e-2),
    st.floats(0.0, 10.0),
)
def test_damping_is_the_weighted_error_norm_plus_the_floor(
    direction: list[float], floor: float, weight: float
) -> None:
    backend = ErrorDampedLeastSquaresBackend(error_weight=weight, lambda_sq_floor=floor)
    bound(backend)
    xdot = np.array(direction)
    e = 0.02 * xdot  # the LM-step reading: e = dt ẋ
    assert backend.damping_for(xdot) == pytest.approx(weight * e @ e + floor, rel=1e-12, abs=1e-300)
    # Defining property: λ² → w̄_N as e → 0, monotonically.
    values = [backend.damping_for(xdot * s) for s in (1.0, 0.1, 1e-3, 1e-6, 0.0)]
    assert values == sorted(values, reverse=True)
    assert values[-1] == floor


def test_per_row_weights_and_the_set_point_horizon() -> None:
    backend = ErrorDampedLeastSquaresBackend(error_weight=[2.0, 0.5], error_horizon=0.1)
    bound(backend)
    xdot = np.array([1.0, 2.0])  # clik with K = 10 /s and a held target: e = ẋ/K
    assert backend.damping_for(xdot) == pytest.approx(2.0 * 0.01 + 0.5 * 0.04 + 1e-3)
    capped = ErrorDampedLeastSquaresBackend(error_weight=1e6, max_lambda_sq=0.5)
    bound(capped)
    assert capped.damping_for(xdot) == 0.5


def test_solution_is_dls_with_that_damping_and_finite_at_exact_singularity() -> None:
    backend = ErrorDampedLeastSquaresBackend(error_weight=5.0, lambda_sq_floor=1e-3)
    arm = bound(backend)
    for q in (np.array([0.3, 0.5, -0.4]), np.array([0.2, 0.0, 0.0])):  # the second: stretched
        state = KinematicState.compute(arm, q)
        xdot = np.array([0.7, -1.1])
        out = backend.solve(state, xdot, np.zeros(3))
        mu = backend.damping_for(xdot)
        J = state.jacobian
        np.testing.assert_allclose(out.qdot, J.T @ np.linalg.solve(J @ J.T + mu * np.eye(2), xdot))
        assert out.damping == pytest.approx(np.sqrt(mu))
        assert np.all(np.isfinite(out.qdot))
    # Floor 0 and zero error at an exact singularity: zero motion, not 0/0.
    plain = ErrorDampedLeastSquaresBackend(lambda_sq_floor=0.0)
    bound(plain)
    state = KinematicState.compute(arm, np.array([0.2, 0.0, 0.0]))
    np.testing.assert_array_equal(plain.solve(state, np.zeros(2), np.zeros(3)).qdot, 0.0)
    huge = plain.solve(state, np.array([1e200, 1e200]), np.zeros(3))
    assert np.all(np.isfinite(huge.qdot))


def test_near_target_it_is_the_pseudoinverse_far_away_it_damps() -> None:
    backend = ErrorDampedLeastSquaresBackend(error_weight=100.0, lambda_sq_floor=0.0)
    arm = bound(backend)
    state = KinematicState.compute(arm, np.array([0.1, 0.02, 0.02]))  # near stretch
    small = np.array([1e-4, 1e-4])
    np.testing.assert_allclose(
        backend.solve(state, small, np.zeros(3)).qdot,
        damped_least_squares(state, small, 0.0),
        rtol=1e-3,
    )
    far = np.array([5.0, 5.0])
    assert np.linalg.norm(backend.solve(state, far, np.zeros(3)).qdot) < np.linalg.norm(
        damped_least_squares(state, far, 0.0)
    )


@pytest.mark.parametrize(
    ("params", "message"),
    [
        ({"error_weight": -1.0}, "error_weight: must be a finite number >= 0 or a list"),
        ({"error_weight": float("nan")}, "error_weight: must be a finite number >= 0"),
        ({"error_weight": [1.0, -2.0]}, "error_weight: must be a finite number >= 0 or a list"),
        ({"error_weight": "x"}, "error_weight: must be a finite number >= 0 or a list of them"),
        ({"lambda_sq_floor": float("inf")}, "lambda_sq_floor: must be a finite number"),
        ({"error_horizon": 0.0}, "error_horizon: must be a finite number > 0 [s] or None"),
        ({"max_lambda_sq": -1.0}, "max_lambda_sq: must be a finite number > 0"),
        (
            {"lambda_sq_floor": 1.0, "max_lambda_sq": 0.5},
            "max_lambda_sq: must be >= lambda_sq_floor",
        ),
    ],
)
def test_bad_parameters_name_the_field(params: dict[str, object], message: str) -> None:
    with pytest.raises(ParameterError) as info:
        ErrorDampedLeastSquaresBackend(**params)  # type: ignore[arg-type]
    assert str(info.value).startswith(message)


def test_per_row_weight_of_the_wrong_length() -> None:
    with pytest.raises(DimensionError, match="error_weight: expected shape"):
        bound(ErrorDampedLeastSquaresBackend(error_weight=[1.0, 1.0, 1.0]))


@pytest.mark.parametrize(
    ("backend", "key", "message"),
    [
        ("dls_error", "damping_floor", "renamed to lambda_sq_floor, the same number (it is λ²"),
        ("dls_error", "max_damping", "renamed to max_lambda_sq, the same number (it is λ²"),
        ("sigma_lm", "damping_floor", "renamed to lambda_sq_floor, the same number (it is λ²"),
    ],
)
def test_old_names_are_refused_with_the_new_name(backend: str, key: str, message: str) -> None:
    with pytest.raises(ParameterError) as info:
        registry.create(registry.BACKENDS, backend, {key: 1e-4}, "backend")
    assert str(info.value).startswith(f"backend.{key}: {message}")
    assert "\n" not in str(info.value)
