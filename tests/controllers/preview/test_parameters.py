"""Issue 37 (and 39's shape): one frozen PreviewParameters, keyword-only; the ``arm`` peak rule."""

from __future__ import annotations

import dataclasses
import inspect
import math

import numpy as np
import pytest

from otmm_qp.exceptions import ParameterError
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.state import KinematicState
from otmm_qp.trajectories.circle import CircleTrajectory
from otmm_qp.validation import declaration_problems
from otmm_qp_controllers.preview import (
    CausalPreviewBackend,
    PreviewBackend,
    TwoRatePreviewBackend,
)
from otmm_qp_controllers.preview.parameters import PREVIEW_CONSTRAINTS, PreviewParameters

DT = 0.02


def _fields() -> dict[str, object]:
    return {f.name: f.default for f in dataclasses.fields(PreviewParameters)}


@pytest.mark.parametrize("cls", [PreviewBackend, CausalPreviewBackend, TwoRatePreviewBackend])
def test_every_preview_parameter_is_keyword_only_with_the_objects_default(cls: type) -> None:
    """The constructors list exactly PreviewParameters' fields (two-rate: less working_set,
    plus its own), keyword-only, with the same defaults; the declarations match them."""
    signature = inspect.signature(cls.__init__)
    params = {n: p for n, p in signature.parameters.items() if n != "self"}
    assert all(p.kind is p.KEYWORD_ONLY for p in params.values())
    fields = _fields()
    if cls is TwoRatePreviewBackend:
        del fields["working_set"]
    for name, default in fields.items():
        assert params[name].default == default, name
    own = {"every", "tracker_regularization", "sliced"} if cls is TwoRatePreviewBackend else set()
    assert set(params) - set(fields) == own
    assert declaration_problems(cls) == []
    with pytest.raises(TypeError):
        cls(1.0)


def test_the_backend_keeps_its_parameters_whole_and_frozen() -> None:
    backend = PreviewBackend(horizon=0.5, knots=8, peak=0.3, peak_scale="arm")
    p = backend.parameters
    assert (p.horizon, p.knots, p.peak, p.peak_scale) == (0.5, 8, 0.3, "arm")
    assert p == PreviewParameters(horizon=0.5, knots=8, peak=0.3, peak_scale="arm")
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.horizon = 2.0  # type: ignore[misc]
    two = TwoRatePreviewBackend(every=5, horizon=0.4, peak_jump=0.2)
    assert (two.parameters.horizon, two.parameters.peak_jump, two.every) == (0.4, 0.2, 5)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("peak_scale", "joint"),
        ("peak", -1.0),
        ("peak_jump", math.nan),
        ("horizon", 0.0),
        ("knots", 0),
        ("infeasible_policy", "ignore"),
    ],
)
def test_a_bad_value_names_its_field(field: str, value: object) -> None:
    assert field in PREVIEW_CONSTRAINTS
    for build in (PreviewParameters, PreviewBackend, TwoRatePreviewBackend):
        with pytest.raises(ParameterError, match=field):
            build(**{field: value})


def _first_plan(backend: PreviewBackend, robot: PlanarArm, trajectory: CircleTrajectory, q0):  # type: ignore[no-untyped-def]
    backend.bind(robot, DT)
    backend.attach(trajectory)
    backend.reset()
    for _ in range(5):  # into the motion: the window's speed is non-zero
        output = backend.solve(KinematicState.compute(robot, q0), np.zeros(2), np.zeros(3))
    return output


@pytest.mark.parametrize("period", [1.5, 3.0])
def test_the_arm_rule_is_the_absolute_rule_at_the_scaled_weights(period: float) -> None:
    """With ``peak_scale: arm`` the QP's epigraph costs are ω̂·v̄²/q̇_lim, v̄ the fastest chord
    speed of the window so far (computed here from the path itself) and q̇_lim the slowest
    joint's limit; the step equals the ``absolute`` backend's with those weights."""
    limits = [2.0, 1.5, 3.0]
    robot = PlanarArm([1.0, 0.8, 0.5], velocity_limits=limits)
    q0 = np.array([0.3, 0.9, 0.6])
    start = robot.forward(q0)
    trajectory = CircleTrajectory(start, centre=start - [0.3, 0.0], radius=0.3, period=period)
    horizon, peak, peak_jump = 0.5, 0.4, 2.0
    arm = _first_plan(
        PreviewBackend(horizon=horizon, peak=peak, peak_jump=peak_jump, peak_scale="arm"),
        robot, trajectory, q0,
    )  # fmt: skip
    speed = max(  # the fastest window of the five steps so far
        float(np.linalg.norm(trajectory.sample(t + horizon)[0] - trajectory.sample(t)[0])) / horizon
        for t in DT * np.arange(5)
    )
    scale = speed**2 / min(limits)
    q = arm.details.problem.q
    assert q[-2] == pytest.approx(peak * scale, rel=1e-9)
    assert q[-1] == pytest.approx(peak_jump * scale, rel=1e-9)
    absolute = _first_plan(
        PreviewBackend(horizon=horizon, peak=peak * scale, peak_jump=peak_jump * scale),
        robot, trajectory, q0,
    )  # fmt: skip
    np.testing.assert_allclose(arm.qdot, absolute.qdot, rtol=1e-9, atol=1e-12)


def test_the_arm_rule_weighs_a_faster_motion_by_its_squared_speed() -> None:
    """The same circle twice as fast, the window covering the same part of it (``H/T`` kept):
    the same chord in half the time, v̄ doubled, the weight × 4."""
    robot = PlanarArm([1.0, 0.8, 0.5], velocity_limits=[2.0] * 3)
    q0 = np.array([0.3, 0.9, 0.6])
    start = robot.forward(q0)
    weights = []
    for period, horizon in ((3.0, 0.6), (1.5, 0.3)):  # the window covers the same phase
        trajectory = CircleTrajectory(start, centre=start - [0.3, 0.0], radius=0.3, period=period)
        backend = PreviewBackend(horizon=horizon, knots=8, peak=1.0, peak_scale="arm")
        backend.bind(robot, DT)
        backend.attach(trajectory)
        backend.reset()
        output = backend.solve(KinematicState.compute(robot, q0), np.zeros(2), np.zeros(3))
        weights.append(float(output.details.problem.q[-1]))
    assert weights[1] == pytest.approx(4.0 * weights[0], rel=1e-9)


def test_the_arm_rules_speed_never_falls_within_an_episode_and_restarts_with_it() -> None:
    """At the end of the motion (the window's chord 0) the weight keeps the episode's largest;
    a reset starts from the first window again."""
    robot = PlanarArm([1.0, 0.8, 0.5], velocity_limits=[2.0] * 3)
    q0 = np.array([0.3, 0.9, 0.6])
    start = robot.forward(q0)
    trajectory = CircleTrajectory(start, centre=start - [0.3, 0.0], radius=0.3, period=0.6)
    backend = PreviewBackend(horizon=0.2, knots=6, peak=1.0, peak_scale="arm")
    backend.bind(robot, DT)
    backend.attach(trajectory)
    backend.reset()
    state = KinematicState.compute(robot, q0)
    weights = []
    for _ in range(45):  # through the motion (0.6 s) into the hold
        output = backend.solve(state, np.zeros(2), np.zeros(3))
        weights.append(float(output.details.problem.q[-1]))
    assert weights[-1] > 0.0
    assert all(b >= a for a, b in zip(weights, weights[1:], strict=False))
    assert max(weights) > weights[0]
    backend.reset()
    first = backend.solve(state, np.zeros(2), np.zeros(3))
    assert float(first.details.problem.q[-1]) == weights[0]


def test_the_window_speed_is_the_same_with_or_without_the_steps_residuals() -> None:
    """``speed`` reuses x_d(t) and x_d(t + H) of the residuals at the same t (one vectorised
    call), else evaluates both ends itself: the same number either way."""
    from otmm_qp_controllers.preview.targets import TrajectoryTargets

    robot = PlanarArm([1.0, 0.8, 0.5], velocity_limits=[2.0] * 3)
    q0 = np.array([0.3, 0.9, 0.6])
    start = robot.forward(q0)
    trajectory = CircleTrajectory(
        start, centre=start - [0.3, 0.0], radius=0.3, period=1.5, profile="quintic"
    )
    taus = np.array([0.02, 0.04, 0.2, 0.5])
    state = KinematicState.compute(robot, q0)
    alone = TrajectoryTargets(trajectory, taus).speed(robot, state, np.zeros(2), 0.3)
    targets = TrajectoryTargets(trajectory, taus)
    out = np.empty((4, 2))
    targets.residuals(robot, state, np.zeros(2), 0.3, [state.x] * 2, out, 0)
    targets.residuals(robot, state, np.zeros(2), 0.3, [state.x] * 2, out, 2)
    assert alone > 0.0
    assert targets.speed(robot, state, np.zeros(2), 0.3) == pytest.approx(alone, rel=1e-12)
    other = TrajectoryTargets(trajectory, taus).speed(robot, state, np.zeros(2), 1.3)
    assert other != pytest.approx(alone, rel=1e-6)  # the cache answers its own t only
    assert targets.speed(robot, state, np.zeros(2), 1.3) == other
