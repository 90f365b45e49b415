"""The rate limiter on the command path and the limit that models it (issue 29, ``franka_fci``).

* the stage: every period's change of the command is at most ``a·dt`` and the command is reached
  when it is within that; an unlimited joint passes through; it declares ``a``;
* the bound: at it, the limiter's travel ``v dt + v²/(2a)`` equals the distance left;
* the invariant: under a rate limiter, a latency and a lag (hypothesis-drawn) and commands
  drawn anywhere in the box, every one the worst the box allows, the true joint position never
  passes its limit, for both readings of the rest point (``measured``, ``command``); without the
  limiter's model the same box does pass it on a fixed case;
* the chain refuses a rate limiter after a lag; rate limits of different joint counts do not
  combine.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp.exceptions import ConfigError, DimensionError, ParameterError
from otmm_qp.limits import Box, PredictedPositionLimit
from otmm_qp.plants import DelayPlant, LagPlant, PlantChain
from otmm_qp.plants.declaration import PlantDeclaration, combine
from otmm_qp.plants.rate_limit import RateLimitPlant
from otmm_qp.robots.planar_arm import PlanarArm

DT = 0.02  # [s]


def test_the_stage_limits_each_change_to_a_dt() -> None:
    arm = PlanarArm([1.0, 1.0, 1.0])
    stage = RateLimitPlant([5.0, 10.0, math.inf])
    stage.reset(arm, np.zeros(3), DT)
    first = stage.command(np.array([1.0, 1.0, 1.0]))
    np.testing.assert_allclose(first, [0.1, 0.2, 1.0], rtol=0, atol=1e-15)
    second = stage.command(np.array([0.15, -1.0, -3.0]))
    np.testing.assert_allclose(second, [0.15, 0.0, -3.0], rtol=0, atol=1e-15)
    assert stage.declares(DT) == PlantDeclaration(acceleration=(5.0, 10.0, math.inf))
    assert stage.label() == "rate_limit(a=5/10/inf)"
    stage.reset(arm, np.zeros(3), DT)  # a new run starts at rest
    np.testing.assert_allclose(stage.command(np.ones(3)), [0.1, 0.2, 1.0], atol=1e-15)


def test_a_per_joint_limit_of_the_wrong_length_is_refused_at_reset() -> None:
    with pytest.raises(DimensionError):
        RateLimitPlant([1.0, 2.0]).reset(PlanarArm([1.0, 1.0, 1.0]), np.zeros(3), DT)


def test_the_chain_refuses_a_rate_limit_after_a_lag() -> None:
    with pytest.raises(ConfigError, match="before every lag"):
        PlantChain([LagPlant(0.01), RateLimitPlant(5.0)])
    PlantChain([RateLimitPlant(5.0), DelayPlant(2), LagPlant(0.01)])  # before: modelled
    with pytest.raises(ConfigError, match="cannot be combined"):
        PlantChain([RateLimitPlant([1.0, 2.0]), RateLimitPlant([1.0, 2.0, 3.0])])


def test_rate_limits_combine_to_the_stricter() -> None:
    one, two = PlantDeclaration(acceleration=(5.0,)), PlantDeclaration(acceleration=(7.0, 3.0))
    both = combine([one, two])
    assert both.acceleration == (5.0, 3.0)
    assert combine([PlantDeclaration(delay=1)]).acceleration == ()


def _box(limit: PredictedPositionLimit, arm: PlanarArm, theta: float) -> Box:
    limit.bind(arm, DT)
    out = Box(np.empty(1), np.empty(1))
    return limit.compute_box(np.array([theta]), np.zeros(1), out)


@given(theta=st.floats(-0.99, 0.99), a=st.floats(0.5, 50.0))
def test_at_the_bound_the_limiter_stops_at_the_limit(theta: float, a: float) -> None:
    """``v dt + v²/(2a) = d`` at the bound (the position box with gain 1 does not bind)."""
    arm = PlanarArm([1.0], limits=[[-1.0, 1.0]], velocity_limits=[1e6])
    limit = PredictedPositionLimit(gain=1.0, rate_limit=a)
    box = _box(limit, arm, theta)
    for v, d in ((box.upper[0], 1.0 - theta), (-box.lower[0], theta + 1.0)):
        assert v >= 0.0
        assert math.isclose(v * DT + v * v / (2 * a), d, rel_tol=1e-9, abs_tol=1e-12)


def _drive(
    arm: PlanarArm,
    stages: list,
    limit: PredictedPositionLimit,
    q0: np.ndarray,
    picks: list[list[float]],
) -> np.ndarray:
    """True positions (steps, nv) under commands at fractions ``picks`` of each step's box."""
    plant = PlantChain(stages)
    limit.declare_plant(plant.declares(DT))
    limit.bind(arm, DT)
    limit.reset()
    plant.reset(arm, q0, DT)
    q, previous, trace = q0.copy(), np.zeros(arm.nv), [q0.copy()]
    box = Box(np.empty(arm.nv), np.empty(arm.nv))
    for fractions in picks:
        limit.compute_box(plant.measure(q), previous, box)
        lower, upper = box.lower, np.maximum(box.upper, box.lower)
        command = lower + np.asarray(fractions) * (upper - lower)
        q = plant.advance(q, command).q
        previous = command
        trace.append(q.copy())
    return np.array(trace)


def _excess(arm: PlanarArm, trace: np.ndarray) -> float:
    lower, upper = arm.position_limits
    return float(np.max(np.maximum(trace - upper, lower - trace)))


@settings(max_examples=40, deadline=None)
@given(
    n=st.integers(1, 3),
    a=st.floats(0.5, 30.0),
    delay=st.integers(0, 3),
    tau=st.sampled_from([0.0, 0.002, 0.01, 0.03]),
    reference=st.sampled_from(["measured", "command"]),
    start=st.floats(0.0, 1.0),
    picks=st.lists(
        st.lists(st.sampled_from([0.0, 1.0, 0.5, 0.9, 0.1]), min_size=3, max_size=3),
        min_size=10,
        max_size=120,
    ),
)
def test_the_joint_never_passes_its_limit_behind_a_rate_limiter(
    n: int,
    a: float,
    delay: int,
    tau: float,
    reference: str,
    start: float,
    picks: list[list[float]],
) -> None:
    """Any command the box allows, after a rate limiter, a latency and a lag: θ stays inside."""
    arm = PlanarArm([1.0] * n, limits=[[-0.5, 0.4]] * n, velocity_limits=[4.0] * n)
    stages: list = [RateLimitPlant(a), DelayPlant(delay)]
    if tau > 0.0:
        stages.append(LagPlant(tau))
    q0 = np.full(n, -0.5 + 0.9 * start)
    limit = PredictedPositionLimit(gain=1.0, reference=reference)
    trace = _drive(arm, stages, limit, q0, [p[:n] for p in picks])
    assert np.all(np.isfinite(trace))
    assert _excess(arm, trace) <= 1e-9


def test_without_the_limiter_model_the_box_passes_the_limit() -> None:
    """The case the model is for: full speed at a limit behind a 2 rad/s² limiter."""
    arm = PlanarArm([1.0], limits=[[-1.0, 1.0]], velocity_limits=[3.0])
    picks = [[1.0]] * 150  # always the box's upper bound: straight at the limit
    blind = PredictedPositionLimit(gain=1.0, rate_limit=None)
    seen = PredictedPositionLimit(gain=1.0)  # rate_limit: plant
    assert _excess(arm, _drive(arm, [RateLimitPlant(2.0)], blind, np.zeros(1), picks)) > 0.05
    modelled = _drive(arm, [RateLimitPlant(2.0)], seen, np.zeros(1), picks)
    assert _excess(arm, modelled) <= 1e-9
    assert modelled[-1, 0] > 0.99  # it still reaches the limit


def test_an_unlimited_scalar_is_accepted_where_its_message_says_so() -> None:
    """``inf`` ("unlimited") as one number, not only inside a per-joint list; NaN and −inf not."""
    arm = PlanarArm([1.0, 1.0])
    stage = RateLimitPlant(math.inf)
    stage.reset(arm, np.zeros(2), DT)
    np.testing.assert_array_equal(stage.command(np.array([3.0, -2.0])), [3.0, -2.0])
    PredictedPositionLimit(deceleration=math.inf, rate_limit=math.inf)
    for bad in (math.nan, -math.inf):
        with pytest.raises(ParameterError, match="acceleration"):
            RateLimitPlant(bad)
