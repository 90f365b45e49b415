import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from otmm_qp.exceptions import DimensionError, NotWithinJointLimits, ParameterError
from otmm_qp.robots import PlanarArm

lengths = st.lists(st.floats(0.1, 2.0), min_size=1, max_size=6)


@given(lengths=lengths, seed=st.integers(0, 2**31 - 1))
def test_jacobian_matches_central_finite_differences(lengths: list[float], seed: int) -> None:
    arm = PlanarArm(lengths)
    q = np.random.default_rng(seed).uniform(-np.pi, np.pi, arm.nv)
    h = 1e-6
    numeric = np.column_stack(
        [(arm.forward(q + h * e) - arm.forward(q - h * e)) / (2 * h) for e in np.eye(arm.nv)]
    )
    np.testing.assert_allclose(arm.jacobian(q), numeric, atol=1e-7)


def test_two_link_forward_kinematics_matches_the_paper_formula() -> None:
    arm = PlanarArm([1.0, 0.8])
    q = np.array([0.927, -2.5])
    expected = [np.cos(q[0]) + 0.8 * np.cos(q.sum()), np.sin(q[0]) + 0.8 * np.sin(q.sum())]
    np.testing.assert_allclose(arm.forward(q), expected, atol=1e-15)
    # det J = l1 l2 sin q2: zero at q2 = 0, the paper's singular configuration.
    assert abs(np.linalg.det(arm.jacobian(q)) - 0.8 * np.sin(q[1])) < 1e-12
    assert np.linalg.svd(arm.jacobian(np.zeros(2)))[1][-1] == pytest.approx(0.0, abs=1e-15)


def test_reach_annulus() -> None:
    arm = PlanarArm([1.0, 0.8])
    assert arm.can_reach(np.array([1.8, 0.0]))
    assert not arm.can_reach(np.array([1.81, 0.0]))
    assert not arm.can_reach(np.array([0.1, 0.0]))  # inner radius 0.2 m


def test_bad_inputs_name_the_field() -> None:
    with pytest.raises(ParameterError, match="link_lengths: every length must be > 0"):
        PlanarArm([1.0, -0.5])
    with pytest.raises(DimensionError, match=r"limits: expected shape \(2, 2\)"):
        PlanarArm([1.0, 0.8], limits=[[0, 1]])
    arm = PlanarArm([1.0, 0.8], limits=[[-1, 1], [-1, 1]])
    with pytest.raises(NotWithinJointLimits, match="joint 'joint2' = 1.5 is outside its limits"):
        arm.check_start(np.array([0.0, 1.5]))
    with pytest.raises(DimensionError, match=r"q0: expected shape \(2,\), got \(3,\)"):
        arm.check_start(np.zeros(3))


def test_paper_sri_threshold_w0() -> None:
    """configs/paper.yaml's SRI w0 is |det J| = l1 l2 |sin q2| where σ_min = 0.05."""
    from scipy.optimize import brentq

    arm = PlanarArm([1.0, 0.8])
    q2 = brentq(lambda a: np.linalg.svd(arm.jacobian(np.array([0.0, a])))[1][-1] - 0.05, 1e-6, 1.0)
    assert 0.8 * abs(np.sin(q2)) == pytest.approx(0.0983028, abs=1e-7)
