"""ServoScalingFilter: the scale law, the direction test, the report."""

from __future__ import annotations

import numpy as np
import pytest

from otmm_qp.exceptions import ParameterError
from otmm_qp.filters.servo_scaling import ServoScalingFilter
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.state import KinematicState

UR5 = PinocchioArm(name="ur5", task="pose")


def test_scale_law() -> None:
    f = ServoScalingFilter(lower_threshold=10.0, hard_stop_threshold=30.0, leaving_factor=2.0)
    assert f.scale(5.0, True) == 1.0
    assert f.scale(20.0, True) == pytest.approx(0.5)
    assert f.scale(30.0, True) == 0.0
    assert f.scale(np.inf, False) == 0.0
    assert f.scale(20.0, False) == 1.0  # band [20, 60] when leaving
    assert f.scale(40.0, False) == pytest.approx(0.5)


def _near_wrist(theta5: float) -> KinematicState:
    theta = np.array([0.0, -1.2, 1.5, -1.8, theta5, 0.0])
    return KinematicState.compute(UR5, UR5.configuration(theta))


def test_direction_test_approaching_and_leaving() -> None:
    f = ServoScalingFilter(lower_threshold=5.0, hard_stop_threshold=1e4, leaving_factor=3.0)
    f.bind(UR5, 0.01)
    state = _near_wrist(0.02)
    kappa = f.condition_number(state.sigma, 6)
    # Joint motion decreasing theta5 (toward 0) is toward the singularity.
    toward = state.task_jacobian @ np.array([0, 0, 0, 0, -1.0, 0])
    away = -toward
    out_toward = f.apply(state, toward)
    assert f.approaching
    out_away = f.apply(state, away)
    assert not f.approaching
    assert out_toward.report.p == pytest.approx(1.0 - f.scale(kappa, True))
    assert out_away.report.p < out_toward.report.p
    np.testing.assert_allclose(out_toward.xdot, (1.0 - out_toward.report.p) * toward)
    assert out_toward.report.removed == pytest.approx(out_toward.report.p * np.linalg.norm(toward))


def test_unbound_filter_is_conservative() -> None:
    f = ServoScalingFilter(lower_threshold=5.0, hard_stop_threshold=1e4)
    state = _near_wrist(0.02)
    f.apply(state, state.task_jacobian @ np.array([0, 0, 0, 0, 1.0, 0]))
    assert f.approaching


def test_regular_configuration_untouched_and_singular_stops() -> None:
    f = ServoScalingFilter()
    f.bind(UR5, 0.01)
    regular = KinematicState.compute(UR5, UR5.configuration(np.array([0, -1.2, 1.5, -1.8, 1.2, 0])))
    xdot = np.ones(6)
    if f.condition_number(regular.sigma, 6) < 17.0:
        out = f.apply(regular, xdot)
        assert not out.report.active and out.xdot is xdot
    singular = _near_wrist(0.0)
    out = f.apply(singular, xdot)
    assert out.report.active and out.report.p == 1.0
    np.testing.assert_array_equal(out.xdot, 0.0)


def test_bad_thresholds() -> None:
    with pytest.raises(ParameterError) as info:
        ServoScalingFilter(lower_threshold=20.0, hard_stop_threshold=10.0)
    assert str(info.value) == (
        "hard_stop_threshold: must be finite and > lower_threshold (20.0), got 10.0"
    )


def test_moveit_rule_matches_servo() -> None:
    """Servo: band [17, 30] approaching, [17, 17 + 13·2] leaving, halt at κ ≥ 30 either way."""
    f = ServoScalingFilter(rule="moveit")
    assert f.scale(17.0, True) == 1.0 and f.scale(17.0, False) == 1.0
    assert f.scale(23.5, True) == pytest.approx(0.5)
    assert f.scale(23.5, False) == pytest.approx(1.0 - 6.5 / 26.0)
    assert f.scale(30.0, False) == 0.0 and f.scale(np.inf, False) == 0.0
    band = ServoScalingFilter()
    assert band.scale(23.5, False) == 1.0  # the band rule starts at 34 when leaving
    assert band.scale(40.0, False) > 0.0  # and lets a leaving command through above 30
    with pytest.raises(ParameterError, match="rule: must be 'band' or 'moveit', got 'x'"):
        ServoScalingFilter(rule="x")
