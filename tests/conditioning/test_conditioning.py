"""Output conditioning stages: speed scaling, jerk limiting (Ruckig), position clipping."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from otmm_qp import registry
from otmm_qp.conditioning import build_conditioning
from otmm_qp.exceptions import ConfigError, DimensionError
from otmm_qp.robots.planar_arm import PlanarArm

DT = 0.01
LIMITS = [1.0, 2.0, 0.5]


def arm() -> PlanarArm:
    return PlanarArm(
        [1.0, 0.8, 0.5],
        velocity_limits=LIMITS,
        limits=[[-2.0, 2.0], [-2.5, 2.5], [-1.0, 1.0]],
    )


velocities = arrays(np.float64, 3, elements=st.floats(-50.0, 50.0))


def test_registered_and_off_by_default() -> None:
    assert {"speed_scale", "jerk_limit", "position_clip"} <= set(
        registry.available(registry.CONDITIONING)
    )
    none = build_conditioning(None)
    qdot = np.array([1.0, 2.0, 3.0])
    assert none.apply(np.zeros(3), qdot) is qdot and none.label() == "none"


@given(velocities, st.floats(0.1, 1.0))
def test_speed_scaling_is_parallel_and_within_limits(qdot: np.ndarray, margin: float) -> None:
    stage = build_conditioning([{"type": "speed_scale", "margin": margin}])
    stage.reset(arm(), DT)
    out = stage.apply(np.zeros(3), qdot)
    assert np.all(np.abs(out) <= margin * np.array(LIMITS) * (1 + 1e-12))
    scale = np.linalg.norm(out) / max(np.linalg.norm(qdot), 1e-300)
    assert np.allclose(out, scale * qdot, atol=1e-12)  # same direction, one factor
    assert scale <= 1.0 + 1e-12
    if np.all(np.abs(qdot) <= margin * np.array(LIMITS)):
        assert np.array_equal(out, qdot)
    else:  # the smallest scale that fits: one joint sits exactly at its limit
        assert np.max(np.abs(out) / (margin * np.array(LIMITS))) == pytest.approx(1.0)


@given(st.lists(velocities, min_size=5, max_size=30), st.floats(0.5, 20.0), st.floats(5.0, 500.0))
def test_jerk_limit_holds_the_sampled_bounds(
    targets: list[np.ndarray], a_max: float, j_max: float
) -> None:
    stage = build_conditioning([{"type": "jerk_limit", "acceleration": a_max, "jerk": j_max}])
    stage.reset(arm(), DT)
    sent = np.array([np.zeros(3)] + [stage.apply(np.zeros(3), t) for t in targets])
    first = np.diff(sent, axis=0)
    assert np.all(np.abs(first) <= a_max * DT * (1 + 1e-6) + 1e-12)
    second = np.diff(sent, n=2, axis=0)
    assert np.all(np.abs(second) <= j_max * DT**2 * (1 + 1e-6) + 1e-12)


def test_jerk_limit_reaches_a_held_target() -> None:
    stage = build_conditioning([{"type": "jerk_limit", "acceleration": 5.0, "jerk": 50.0}])
    stage.reset(arm(), DT)
    target = np.array([0.5, -1.0, 0.2])
    for _ in range(200):
        out = stage.apply(np.zeros(3), target)
    assert out == pytest.approx(target, abs=1e-9)


@given(arrays(np.float64, 3, elements=st.floats(-0.99, 0.99)), velocities)
def test_position_clip_keeps_the_euler_step_inside(theta: np.ndarray, qdot: np.ndarray) -> None:
    robot = arm()
    stage = build_conditioning([{"type": "position_clip"}])
    stage.reset(robot, DT)
    out = stage.apply(theta, qdot)
    lower, upper = robot.position_limits
    nxt = robot.integrate(theta, out, DT)
    assert np.all(nxt >= lower - 1e-12) and np.all(nxt <= upper + 1e-12)
    inside = (theta + qdot * DT >= lower) & (theta + qdot * DT <= upper)
    assert np.allclose(out[inside], qdot[inside])


@pytest.mark.parametrize(
    ("spec", "field"),
    [
        ({"type": "speed_scale", "margin": 0.0}, "conditioning.0.margin"),
        ({"type": "speed_scale", "margin": 1.5}, "conditioning.0.margin"),
        ({"type": "jerk_limit", "acceleration": -1.0, "jerk": 1.0}, "conditioning.0.acceleration"),
        ({"type": "jerk_limit", "acceleration": 1.0, "jerk": float("nan")}, "conditioning.0.jerk"),
        ({"type": "clip_everything"}, "conditioning.0"),
    ],
)
def test_bad_parameters_name_the_field(spec: dict[str, object], field: str) -> None:
    with pytest.raises(ConfigError) as info:
        build_conditioning([spec])
    assert str(info.value).startswith(field + ":")


def test_per_joint_limits_must_match_the_arm() -> None:
    stage = build_conditioning([{"type": "jerk_limit", "acceleration": [1.0, 2.0], "jerk": 10.0}])
    with pytest.raises(DimensionError, match="acceleration"):
        stage.reset(arm(), DT)
