"""The predicted-position limit: its prediction is the plant's rest point, and it keeps the limits.

* :class:`CommandPrediction` against the real plant stages: θ + r equals where the joint comes
  to rest when every later command is zero (hypothesis-drawn delays, lags, commands);
* the invariant: on delay / lag / sensor plants drawn by hypothesis (with arms, starts and task
  velocities), the *true* joint position of ``qp``, ``qp_scaled`` and ``sns`` never leaves its
  limits, while the old ``position`` box does on a fixed case;
* the braking bound is the stopping distance: ``v²/(2a) = d − m`` at the bound; the ramp;
* nothing declared (the ideal plant): the box is ``position``'s bit for bit;
* bad input: a negative or NaN margin, a zero deceleration, a ramp that ends before it starts.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp.controller import Controller
from otmm_qp.exceptions import ParameterError
from otmm_qp.limits import Box, PositionLimit, PredictedPositionLimit
from otmm_qp.limits.command_prediction import CommandPrediction
from otmm_qp.plants import DelayPlant, LagPlant, PlantChain, SensorPlant
from otmm_qp.plants.declaration import PlantDeclaration, combine
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.state import KinematicState
from otmm_qp_controllers.qp import QpBackend
from otmm_qp_controllers.qp.scaled import ScaledQpBackend
from otmm_qp_controllers.sns import SnsBackend

DT = 0.02  # [s]


@settings(max_examples=40, deadline=None)
@given(
    delay=st.integers(0, 4),
    taus=st.lists(st.sampled_from([0.002, 0.01, 0.03]), max_size=2),
    commands=st.lists(st.floats(-3.0, 3.0), min_size=1, max_size=30),
)
def test_theta_plus_residual_is_the_rest_point(
    delay: int, taus: list[float], commands: list[float]
) -> None:
    """After any command history, θ_k + r_k is where the joint stops under zero commands."""
    arm = PlanarArm([1.0])
    stages = [DelayPlant(delay), *(LagPlant(tau) for tau in taus)]
    plant = PlantChain(stages)
    q = np.zeros(1)
    plant.reset(arm, q, DT)
    prediction = CommandPrediction(delay, plant.declares(DT).lags)
    prediction.bind(1, DT)
    previous = np.zeros(1)
    for u in commands:
        residual = prediction.advance(previous)
        command = np.array([u])
        q = plant.advance(q, command).q
        previous = command
    rest = q + prediction.advance(previous)
    for _ in range(delay + 200):  # the slowest lags (30 ms, α ≈ 0.49) settle below 1e-12 rad
        q = plant.advance(q, np.zeros(1)).q
    assert residual.shape == (1,)
    np.testing.assert_allclose(rest, q, rtol=0, atol=1e-9)


def test_declarations_combine() -> None:
    """Latencies add, lags cascade, noises add in variance, servo: the slowest."""
    euler = LagPlant(0.04, update="euler").declares(DT).lags[0]
    assert math.isclose(-math.expm1(-DT / euler), DT / 0.04)  # the same α as the plant's
    assert LagPlant(DT, update="euler").declares(DT).lags == (0.0,)
    both = combine([PlantDeclaration(2, (0.01,), 3e-4, 1e-5), PlantDeclaration(1, (0.02,), 4e-4)])
    assert both.delay == 3 and both.lags == (0.01, 0.02)
    assert math.isclose(both.noise, 5e-4) and both.quantum == 1e-5
    chain = PlantChain([LagPlant(0.02), DelayPlant(2), SensorPlant(noise=1e-4, counts=4096)])
    declared = chain.declares(DT)
    assert declared.delay == 2 and declared.lags == (0.02,) and declared.noise == 1e-4
    assert math.isclose(declared.quantum, 2 * math.pi / 4096)
    assert math.isinf(declared.servo_frequency)


def _run(backend_kind: str, limits: list[dict] | None, arm: PlanarArm, case: dict) -> np.ndarray:
    """The true joint positions (steps, nv) of a closed loop on ``case``'s plant."""
    if backend_kind == "qp":
        backend = QpBackend(limits=limits, infeasible_policy="hold")
    elif backend_kind == "qp_scaled":
        backend = ScaledQpBackend(limits=limits, infeasible_policy="hold")
    else:
        backend = SnsBackend(limits=limits)
    controller = Controller(backend_kind, [], backend)
    plant = PlantChain(case["stages"])
    q = np.array(case["q0"], dtype=float)
    controller.declare_plant(plant.declares(DT))
    controller.bind(arm, DT)
    plant.reset(arm, q, DT)
    previous, trace = np.zeros(arm.nv), [q]
    xdot = np.array(case["xdot"], dtype=float)
    for _ in range(case["steps"]):
        state = KinematicState.compute(arm, plant.measure(q))
        qdot = controller.step(state, xdot, previous).qdot
        q = plant.advance(q, qdot).q
        previous = qdot
        trace.append(q)
    return np.array(trace)


def _excess(arm: PlanarArm, trace: np.ndarray) -> float:
    lower, upper = arm.position_limits
    return float(np.max(np.maximum(trace - upper, lower - trace)))


@st.composite
def _cases(draw: st.DrawFn) -> tuple[PlanarArm, dict]:
    n = draw(st.integers(2, 4))
    lengths = draw(st.lists(st.floats(0.3, 1.2), min_size=n, max_size=n))
    lower = draw(st.lists(st.floats(-2.5, -0.2), min_size=n, max_size=n))
    upper = draw(st.lists(st.floats(0.2, 2.5), min_size=n, max_size=n))
    speeds = draw(st.lists(st.floats(0.5, 3.0), min_size=n, max_size=n))
    arm = PlanarArm(lengths, limits=list(zip(lower, upper, strict=True)), velocity_limits=speeds)
    fractions = draw(st.lists(st.floats(0.0, 1.0), min_size=n, max_size=n))
    q0 = [lo + f * (hi - lo) for lo, hi, f in zip(lower, upper, fractions, strict=True)]
    stages: list = [DelayPlant(draw(st.integers(0, 4)))]
    tau = draw(st.sampled_from([0.0, 0.002, 0.01, 0.03]))
    if tau > 0.0:
        stages.append(LagPlant(tau))
    noise = draw(st.sampled_from([0.0, 1e-4, 1e-3]))
    counts = draw(st.sampled_from([None, 2**12, 2**16]))
    if noise > 0.0 or counts is not None:
        stages.append(SensorPlant(noise=noise, counts=counts, seed=draw(st.integers(0, 99))))
    xdot = draw(st.lists(st.floats(-3.0, 3.0), min_size=2, max_size=2))
    order = draw(st.permutations(stages))
    return arm, {"q0": q0, "stages": list(order), "xdot": xdot, "steps": 60}


# noise_bound 8: the Gaussian noise exceeds the margin with probability ~1e-15 per sample.
PREDICTED = [{"type": "predicted_position", "gain": 0.5, "noise_bound": 8.0}]


@settings(max_examples=25, deadline=None)
@given(case=_cases(), kind=st.sampled_from(["qp", "qp_scaled", "sns"]))
def test_the_true_position_never_leaves_its_limits(case: tuple[PlanarArm, dict], kind: str) -> None:
    """Delay, lag, noise and quantisation in any order: the true θ stays within the limits."""
    arm, spec = case
    trace = _run(kind, PREDICTED, arm, spec)
    assert np.all(np.isfinite(trace))
    assert _excess(arm, trace) <= 1e-9


def test_the_old_box_leaves_the_limits_where_the_new_one_does_not() -> None:
    """The case the limit is for: a lagged, delayed arm driven into a limit."""
    arm = PlanarArm([1.0, 0.8], limits=[[-1.0, 1.0]] * 2, velocity_limits=[2.0, 2.0])
    case = {
        "q0": [0.5, 0.5],
        "stages": [LagPlant(0.03), DelayPlant(2)],
        "xdot": [0.0, 3.0],
        "steps": 80,
    }
    old = _run("qp", [{"type": "position", "gain": 0.5}], arm, case)
    new = _run("qp", None, arm, case)  # the default: predicted_position, from the plant
    assert _excess(arm, old) > 1e-3
    assert _excess(arm, new) <= 1e-9
    assert np.max(new[:, 0]) > 0.99  # the limit is approached, not avoided from afar


def _bound(limit: PredictedPositionLimit, arm: PlanarArm, theta: np.ndarray) -> Box:
    limit.declare_plant(PlantDeclaration())
    limit.bind(arm, DT)
    out = Box(np.empty(arm.nv), np.empty(arm.nv))
    return limit.compute_box(theta, np.zeros(arm.nv), out)


@given(
    theta=st.floats(-0.99, 0.99),
    decel=st.floats(0.5, 50.0),
    margin=st.floats(0.0, 0.005),
)
def test_the_braking_bound_is_the_stopping_distance(
    theta: float, decel: float, margin: float
) -> None:
    """At the bound, a joint decelerating at a_dec stops exactly m short of the limit."""
    arm = PlanarArm([1.0], limits=[[-1.0, 1.0]], velocity_limits=[1e6])
    limit = PredictedPositionLimit(gain=1.0, margin=margin, deceleration=decel)
    box = _bound(limit, arm, np.array([theta]))
    d_up, d_down = 1.0 - margin - theta, theta + 1.0 - margin
    assert box.upper[0] <= math.sqrt(2 * decel * d_up) * (1 + 1e-12)
    assert box.lower[0] >= -math.sqrt(2 * decel * d_down) * (1 + 1e-12)
    # the position box with g = 1 is d/dt; whichever is smaller binds
    np.testing.assert_allclose(
        box.upper[0], min(d_up / DT, math.sqrt(2 * decel * d_up)), rtol=1e-12
    )
    stop = box.upper[0] ** 2 / (2 * decel)  # [rad] travelled braking at a_dec
    assert stop <= d_up * (1 + 1e-9)


def test_the_ramp_is_linear_between_its_distances() -> None:
    """Speed towards a limit: q̇_max beyond d1, 0 within d0, linear in between (Drake's ramp)."""
    arm = PlanarArm([1.0], limits=[[-1.0, 1.0]], velocity_limits=[2.0])
    limit = PredictedPositionLimit(gain=1.0, ramp_start=0.1, ramp_stop=0.0025)
    speeds = []
    for distance in (0.2, 0.1, 0.05125, 0.0025, 0.001):
        box = _bound(limit, arm, np.array([1.0 - distance]))
        speeds.append(min(box.upper[0], 2.0))
    np.testing.assert_allclose(speeds, [2.0, 2.0, 1.0, 0.0, 0.0], atol=1e-12)
    box = _bound(limit, arm, np.array([1.0 - 0.001]))
    assert box.lower[0] == -2.0  # away from the upper limit the ramp does not bind


def test_nothing_declared_is_the_position_box_bit_for_bit() -> None:
    """The ideal plant declares nothing: the same arrays as ``position``."""
    arm = PlanarArm([1.0, 0.5, 0.3], limits=[[-2.0, 2.0]] * 3, velocity_limits=[1.0] * 3)
    rng = np.random.default_rng(3)
    old, new = PositionLimit(0.5), PredictedPositionLimit(0.5)
    new.declare_plant(PlantDeclaration())
    old.bind(arm, DT)
    new.bind(arm, DT)
    for _ in range(20):
        theta, prev = rng.uniform(-2.5, 2.5, 3), rng.uniform(-1, 1, 3)
        a = old.compute_box(theta, prev, Box(np.empty(3), np.empty(3)))
        b = new.compute_box(theta, prev, Box(np.empty(3), np.empty(3)))
        assert np.array_equal(a.lower, b.lower) and np.array_equal(a.upper, b.upper)


@pytest.mark.parametrize(
    ("params", "field"),
    [
        ({"margin": -0.001}, "margin"),
        ({"margin": float("nan")}, "margin"),
        ({"deceleration": 0.0}, "deceleration"),
        ({"deceleration": [1.0, 0.0]}, "deceleration"),
        ({"noise": -1e-4}, "noise"),
        ({"delay": 1.5}, "delay"),
        ({"tau": "auto"}, "tau"),
        ({"ramp_start": 0.001, "ramp_stop": 0.0025}, "ramp_stop"),
    ],
)
def test_bad_parameters_are_one_line(params: dict, field: str) -> None:
    """Each bad value names its field and what is allowed."""
    with pytest.raises(ParameterError) as error:
        PredictedPositionLimit(**params)
    assert error.value.field == field and "\n" not in str(error.value)


def test_a_margin_that_leaves_no_range_is_refused_at_bind() -> None:
    arm = PlanarArm([1.0], limits=[[-0.01, 0.01]])
    with pytest.raises(ParameterError, match="no range"):
        _bound(PredictedPositionLimit(margin=0.01), arm, np.zeros(1))
