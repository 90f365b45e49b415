"""The preview backend (issue 28): knots, the QP's limits, its one-step limit, bad input."""

from __future__ import annotations

import collections
import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from otmm_qp import registry
from otmm_qp.cli import main
from otmm_qp.controller import Controller
from otmm_qp.exceptions import ConfigError, ParameterError, PreviewUnavailable
from otmm_qp.metrics.metrics import MetricSettings, compute_metrics
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.simulation import Episode, Loop, simulate
from otmm_qp.state import KinematicState
from otmm_qp.status import Status
from otmm_qp.trajectories.circle import CircleTrajectory
from otmm_qp.trajectories.held_targets import HeldTargetsTrajectory
from otmm_qp_controllers.preview import (
    CausalPreviewBackend,
    KnotGrid,
    PreviewBackend,
    TwoRatePreviewBackend,
)
from otmm_qp_controllers.preview.backend import KNOTS_PER_SLICE
from otmm_qp_controllers.qp import QpBackend
from otmm_qp_controllers.qp.solvers import Solution

DT = 0.02


def _run(robot, trajectory, q0, backend, duration=1.0, mode="clik"):  # type: ignore[no-untyped-def]
    controller = Controller("preview", [], backend)
    episode = Episode(robot, trajectory, q0, DT, duration, Loop(mode, 10.0))
    result = simulate(episode, controller)
    return result, compute_metrics(result, MetricSettings())


# --- knots ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("horizon", "fine", "knots", "coarse", "expected"),
    [
        (1.0, 4, 16, None, [0.02] * 4 + [0.92 / 12] * 12),
        (0.25, 4, 40, None, [0.02] * 4 + [0.17 / 8] * 8),  # coarse steps ≥ dt
        (0.08, 4, 16, None, [0.02] * 4),
        (0.02, 4, 16, None, [0.02]),
    ],
)
def test_layout(
    horizon: float, fine: int, knots: int, coarse: float | None, expected: list[float]
) -> None:
    grid = KnotGrid.layout(horizon, DT, fine, knots, coarse)
    np.testing.assert_allclose(grid.steps, expected, rtol=1e-12)
    assert grid.horizon == pytest.approx(horizon, rel=1e-12)
    assert grid.count <= knots


def test_layout_with_a_dividing_coarse_step() -> None:
    grid = KnotGrid.layout(1.04, DT, 4, 30, 0.24)
    np.testing.assert_allclose(grid.steps, [0.02] * 4 + [0.24] * 4, rtol=1e-12)


@pytest.mark.parametrize(
    ("args", "field", "words"),
    [
        ((0.01, DT, 4, 16, None), "horizon", "shorter than one control period"),
        ((1.0, DT, 4, 30, 0.03), "coarse_step", "not a multiple of dt"),
        ((1.0, DT, 4, 30, 0.1), "coarse_step", "does not divide"),
        ((1.0, DT, 4, 6, 0.04), "knots", "below the 27 knots"),
        ((1.0, DT, 4, 4, None), "knots", "cannot reach the horizon"),
        ((1.0, DT, 4, 3, None), "knots", "below the 4 fine steps"),
        ((math.nan, DT, 4, 16, None), "horizon", "finite number > 0"),
    ],
)
def test_layout_refusals_are_one_line(args: tuple, field: str, words: str) -> None:  # type: ignore[type-arg]
    with pytest.raises(ParameterError) as caught:
        KnotGrid.layout(*args)
    assert caught.value.field == field
    assert words in str(caught.value)
    assert "\n" not in str(caught.value)


def test_shift_advances_the_plan_by_one_step() -> None:
    grid = KnotGrid.layout(1.0, DT, 4, 16)
    shift = grid.shift_matrix()
    rng = np.random.default_rng(0)
    plan = rng.normal(size=grid.count)
    shifted = shift @ plan
    # Fine segments: the next one moves up (every fine step is dt long).
    np.testing.assert_allclose(shifted[:3], plan[1:4], rtol=1e-12)
    # A constant velocity stays constant, but for the last segment, which ends at the held end.
    constant = shift @ np.ones(grid.count)
    np.testing.assert_allclose(constant[:-1], 1.0, rtol=1e-12)
    h = grid.steps[-1]
    assert constant[-1] == pytest.approx((h - DT) / h, rel=1e-12)
    # The displacement is continuous: d̄_i = P(τ_i + dt) − P(dt), checked against interpolation.
    knots = np.concatenate([[0.0], grid.taus])
    displacement = np.concatenate([[0.0], np.cumsum(grid.steps * plan)])
    expected = np.interp(np.minimum(knots + DT, knots[-1]), knots, displacement)
    np.testing.assert_allclose(
        np.cumsum(grid.steps * shifted), (expected - expected[0])[1:], atol=1e-12
    )


# --- the QP ---------------------------------------------------------------------------------


def _arm() -> PlanarArm:
    return PlanarArm([1.0, 0.8, 0.5], velocity_limits=[2.0, 2.0, 2.0])


@pytest.mark.parametrize("seed", range(4))
def test_one_knot_is_the_one_step_qp(seed: int) -> None:
    """H = dt, one knot, no smoothness: the causal QP is the ``qp`` backend's QP."""
    robot = _arm()
    rng = np.random.default_rng(seed)
    mu = 10.0 ** rng.uniform(-4, -1)
    causal = CausalPreviewBackend(
        horizon=DT,
        knots=1,
        fine_steps=1,
        regularization=mu,
        smoothness=0.0,
        jump=0.0,
        trust_region=0.0,
    )
    one_step = QpBackend(regularization=mu, fast_path=False)
    for backend in (causal, one_step):
        backend.bind(robot, DT)
        backend.reset()
    for _ in range(5):
        q = rng.uniform(-2.5, 2.5, size=3)
        state = KinematicState.compute(robot, q)
        xdot = rng.normal(scale=3.0, size=2)  # large: the speed box binds on some draws
        previous = rng.normal(size=3)
        ours, theirs = causal.solve(state, xdot, previous), one_step.solve(state, xdot, previous)
        np.testing.assert_allclose(ours.qdot, theirs.qdot, atol=1e-6)
        assert ours.status == theirs.status


def test_one_knot_preview_is_the_newton_step() -> None:
    """H = dt with the trajectory: the one-step QP of ẋ = e(x_d(t + dt), x)/dt."""
    robot = _arm()
    q0 = np.array([0.3, 0.9, 0.6])
    trajectory = CircleTrajectory(robot.forward(q0), centre=[1.0, 0.6], radius=0.3, period=3.0)
    preview = PreviewBackend(horizon=DT, knots=1, fine_steps=1, smoothness=0.0, trust_region=0.0)
    one_step = QpBackend(regularization=1e-4, fast_path=False)
    preview.bind(robot, DT)
    preview.attach(trajectory)
    preview.reset()
    one_step.bind(robot, DT)
    q, previous = q0, np.zeros(3)
    for k in range(10):
        state = KinematicState.compute(robot, q)
        command = robot.task_error(trajectory.position((k + 1) * DT), state.x) / DT
        ours = preview.solve(state, command * 0.0, previous)  # the command is not read
        theirs = one_step.solve(state, command, previous)
        np.testing.assert_allclose(ours.qdot, theirs.qdot, atol=1e-6)
        q, previous = q + DT * ours.qdot, ours.qdot


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    links=st.lists(st.floats(0.3, 1.2), min_size=2, max_size=4),
    seed=st.integers(0, 10_000),
    horizon=st.sampled_from([0.1, 0.3, 0.6]),
    speed=st.floats(0.3, 3.0),
    smoothness=st.sampled_from([0.0, 0.1, 10.0]),
    causal=st.booleans(),
)
def test_limits_are_never_violated(
    links: list[float], seed: int, horizon: float, speed: float, smoothness: float, causal: bool
) -> None:
    """Random arms, tight position boxes around q0, slow joints: 0 violations, ideal plant."""
    rng = np.random.default_rng(seed)
    m = len(links)
    q0 = rng.uniform(-1.5, 1.5, size=m)
    room = rng.uniform(0.05, 0.6, size=(2, m))
    limits = [(q - a, q + b) for q, a, b in zip(q0, room[0], room[1], strict=True)]
    robot = PlanarArm(links, limits=[list(pair) for pair in limits], velocity_limits=[speed] * m)
    reach = sum(links)
    trajectory = CircleTrajectory(
        robot.forward(q0), centre=[0.3 * reach, 0.2 * reach], radius=0.5 * reach, period=1.5
    )
    kind = CausalPreviewBackend if causal else PreviewBackend
    backend = kind(horizon=horizon, knots=8, smoothness=smoothness, infeasible_policy="hold")
    result, metrics = _run(robot, trajectory, q0, backend, duration=0.6)
    assert result.error_message is None
    assert metrics["position_violations"] == 0
    assert metrics["velocity_violations"] == 0
    assert np.all(np.isfinite(result.qdot))


def test_tracks_a_reachable_path_and_preview_beats_its_causal_counterpart() -> None:
    robot = _arm()
    q0 = np.array([0.3, 0.9, 0.6])
    start = robot.forward(q0)
    trajectory = CircleTrajectory(start, centre=start - [0.3, 0.0], radius=0.3, period=2.0)
    _, preview = _run(robot, trajectory, q0, PreviewBackend(horizon=0.5), duration=2.0)
    _, causal = _run(robot, trajectory, q0, CausalPreviewBackend(horizon=0.5), duration=2.0)
    assert preview["max_error"] < 2e-3  # [m] on a 0.3 m circle in 2 s
    assert preview["rms_error"] < causal["rms_error"]


@pytest.mark.parametrize("speed", [2.0, 0.6])
def test_the_fast_paths_are_the_qp_optimum(speed: float) -> None:
    """The unconstrained minimiser or the last active set, when kept, is the solver's answer.

    At 0.6 rad/s the speed bounds bind on most steps (the active-set guess is what runs).
    """
    robot = PlanarArm([1.0, 0.8, 0.5], velocity_limits=[speed] * 3)
    q0 = np.array([0.3, 0.9, 0.6])
    start = robot.forward(q0)
    trajectory = CircleTrajectory(start, centre=start - [0.3, 0.0], radius=0.3, period=2.0)
    fast = PreviewBackend(horizon=0.5)
    slow = PreviewBackend(horizon=0.5, fast_path=False)
    for backend in (fast, slow):
        backend.bind(robot, DT)
        backend.attach(trajectory)
        backend.reset()
    q, previous, taken = q0, np.zeros(3), collections.Counter()
    for _ in range(40):
        state = KinematicState.compute(robot, q)
        ours = fast.solve(state, np.zeros(2), previous)
        theirs = slow.solve(state, np.zeros(2), previous)
        np.testing.assert_allclose(ours.qdot, theirs.qdot, atol=1e-7)
        np.testing.assert_allclose(ours.details.plan, theirs.details.plan, atol=1e-6)
        assert ours.status == theirs.status
        taken[ours.details.solution.detail] += 1
        q, previous = q + DT * ours.qdot, ours.qdot
    expected = "unconstrained minimiser feasible" if speed > 1 else "last active set optimal"
    assert taken[expected] > 10, taken


@pytest.mark.parametrize("speed", [2.0, 0.6])
def test_the_peak_term_is_the_plans_peak_speed_and_lowers_it(speed: float) -> None:
    """With ω > 0 the epigraph variable is the plan's peak |v| (or the executed floor) at the
    optimum, every knot keeps |v_ij| ≤ s; a larger ω never raises the first plan's peak (the
    optimal s of min f + ωs is non-increasing in ω) and a large one lowers the executed peak."""
    robot = PlanarArm([1.0, 0.8, 0.5], velocity_limits=[speed] * 3)
    q0 = np.array([0.3, 0.9, 0.6])
    start = robot.forward(q0)
    trajectory = CircleTrajectory(start, centre=start - [0.3, 0.0], radius=0.3, period=1.5)
    peaks, first = [], []
    for weight in (0.0, 0.01, 1.0):
        backend = PreviewBackend(horizon=0.5, peak=weight)
        backend.bind(robot, DT)
        backend.attach(trajectory)
        backend.reset()
        q, previous, floor, executed = q0, np.zeros(3), 0.0, 0.0
        for _ in range(40):
            output = backend.solve(KinematicState.compute(robot, q), np.zeros(2), previous)
            x = output.details.solution.x
            plan = output.details.plan
            if weight > 0.0:
                s = x[-1]
                assert np.all(np.abs(x[:-1]) <= s + 1e-7)
                assert s == pytest.approx(max(floor, np.abs(x[:-1]).max()), abs=1e-6)
            else:
                assert x.shape == (plan.size,)
            if not first or len(first) < len(peaks) + 1:
                first.append(float(np.abs(plan).max()))
            q, previous = q + DT * output.qdot, output.qdot
            floor = executed = max(executed, float(np.abs(output.qdot).max()))
        peaks.append(executed)
    assert first[0] >= first[1] - 1e-7 and first[1] >= first[2] - 1e-7, first
    if speed > 1.0:  # at 0.6 rad/s every row runs at the hard speed limit
        assert peaks[2] < peaks[0], peaks
    assert max(peaks) <= speed * (1.0 + 1e-9), peaks


def test_the_peak_jump_term_is_the_plans_largest_step_change() -> None:
    """With ω_a > 0 the jump variable bounds every per-step change of the plan (the first
    against q̇_prev, the later ones scaled by dt/h̃_i), equals the largest (or the executed
    floor) at the optimum, and a large ω_a lowers the executed largest jump."""
    robot = PlanarArm([1.0, 0.8, 0.5], velocity_limits=[2.0] * 3)
    q0 = np.array([0.3, 0.9, 0.6])
    start = robot.forward(q0)
    trajectory = CircleTrajectory(start, centre=start - [0.3, 0.0], radius=0.3, period=1.5)
    jumps = []
    for weight in (0.0, 1.0):
        backend = PreviewBackend(horizon=0.5, peak=0.01, peak_jump=weight)
        backend.bind(robot, DT)
        backend.attach(trajectory)
        backend.reset()
        h = backend.grid.steps
        scale = np.concatenate([[1.0], DT / (0.5 * (h[:-1] + h[1:]))])
        q, previous, largest = q0, np.zeros(3), 0.0
        for _ in range(40):
            output = backend.solve(KinematicState.compute(robot, q), np.zeros(2), previous)
            x = output.details.solution.x
            if weight > 0.0:
                plan = x[:-2].reshape(-1, 3)
                changes = np.abs(np.diff(np.vstack([previous, plan]), axis=0)) * scale[:, None]
                assert np.all(changes <= x[-1] + 1e-7)
                assert x[-1] == pytest.approx(max(largest, changes.max()), abs=1e-6)
            largest = max(largest, float(np.abs(output.qdot - previous).max()))
            q, previous = q + DT * output.qdot, output.qdot
        jumps.append(largest)
    assert jumps[1] < jumps[0], jumps


def test_information_classes() -> None:
    assert PreviewBackend(horizon=0.5).information == "preview 0.5 s"
    assert CausalPreviewBackend(horizon=0.5).information == "causal"
    assert QpBackend().information == "causal"


# --- run-time failures -------------------------------------------------------------------------


@pytest.mark.parametrize("policy", ["hold", "dls"])
def test_a_failed_solve_falls_back_and_is_counted(
    policy: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    robot = _arm()
    q0 = np.array([0.3, 0.9, 0.6])
    trajectory = CircleTrajectory(robot.forward(q0), centre=[1.0, 0.6], radius=0.3, period=2.0)
    backend = PreviewBackend(horizon=0.2, infeasible_policy=policy, fast_path=False)
    calls = {"n": 0}
    real = type(backend.session).solve

    def flaky(session):  # type: ignore[no-untyped-def]
        calls["n"] += 1
        return Solution(None, False, "forced") if calls["n"] % 3 == 0 else real(session)

    monkeypatch.setattr(type(backend.session), "solve", flaky)
    result, metrics = _run(robot, trajectory, q0, backend, duration=0.3)
    assert result.error_message is None
    assert metrics["status_infeasible"] == 5  # every third of 15 steps
    assert int(np.sum(result.status == Status.INFEASIBLE)) == 5
    assert metrics["velocity_violations"] == 0


def test_a_failed_solve_under_raise_stops_the_run_with_one_line(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    robot = _arm()
    q0 = np.array([0.3, 0.9, 0.6])
    trajectory = CircleTrajectory(robot.forward(q0), centre=[1.0, 0.6], radius=0.3, period=2.0)
    backend = PreviewBackend(horizon=0.2, fast_path=False)
    monkeypatch.setattr(
        type(backend.session), "solve", lambda session: Solution(None, False, "forced")
    )
    result, _ = _run(robot, trajectory, q0, backend, duration=0.3)
    assert result.error_message is not None
    expected = "infeasible QP at step 0: solver 'daqp' found no solution (forced)"
    assert result.error_message == expected


# --- bad input ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("params", "field"),
    [
        ({"horizon": 0.0}, "horizon"),
        ({"horizon": -1.0}, "horizon"),
        ({"horizon": math.nan}, "horizon"),
        ({"horizon": math.inf}, "horizon"),
        ({"knots": 0}, "knots"),
        ({"fine_steps": 1.5}, "fine_steps"),
        ({"smoothness": -1.0}, "smoothness"),
        ({"regularization": 0.0}, "regularization"),
        ({"peak": -0.1}, "peak"),
        ({"peak": math.nan}, "peak"),
        ({"peak_jump": -1.0}, "peak_jump"),
        ({"infeasible_policy": "ignore"}, "infeasible_policy"),
    ],
)
def test_bad_parameters_are_refused_at_construction(params: dict, field: str) -> None:  # type: ignore[type-arg]
    with pytest.raises(ConfigError) as caught:
        registry.create(registry.BACKENDS, "preview", params, "backend")
    assert field in str(caught.value)
    assert "\n" not in str(caught.value)


def test_a_causal_trajectory_is_refused_before_any_step() -> None:
    robot = _arm()
    q0 = np.array([0.3, 0.9, 0.6])
    held = HeldTargetsTrajectory(robot.forward(q0), targets=[[1.2, 0.5]], hold=1.0)
    controller = Controller("preview", [], PreviewBackend(horizon=0.5))
    with pytest.raises(PreviewUnavailable, match="causal"):
        controller.bind(robot, DT, held)
    # The causal counterpart runs on it.
    result, _ = _run(robot, held, q0, CausalPreviewBackend(horizon=0.5), duration=0.2)
    assert result.error_message is None


class _KnownAhead(CircleTrajectory):
    lookahead = 0.5


def test_a_trajectory_known_less_far_ahead_than_the_horizon_is_refused() -> None:
    robot = _arm()
    q0 = np.array([0.3, 0.9, 0.6])
    start = robot.forward(q0)
    trajectory = _KnownAhead(start, centre=start - [0.3, 0.0], radius=0.3, period=2.0)
    PreviewBackend(horizon=0.5).attach(trajectory)  # exactly as far: accepted
    with pytest.raises(PreviewUnavailable, match="known 0.5 s ahead") as caught:
        PreviewBackend(horizon=0.6).attach(trajectory)
    assert caught.value.field == "horizon" and "\n" not in str(caught.value)


def test_filters_in_front_of_a_preview_backend_are_refused() -> None:
    otmm = registry.create(registry.FILTERS, "otmm", {}, "filters.0")
    with pytest.raises(ParameterError, match="filters: backend 'preview' reads the desired path"):
        Controller("p", [otmm], PreviewBackend())
    Controller("c", [otmm], CausalPreviewBackend())  # the causal counterpart reads the command


RUN = """
name: preview-bad
dt: 0.02
loop_modes: [clik]
experiments:
  - name: A
    robot: {{type: planar, link_lengths: [1.0, 0.8]}}
    q0: [0.927, -2.5]
    trajectory: {trajectory}
    duration: 0.4
    controllers:
      - name: preview
        backend: {backend}
"""
CIRCLE = "{type: circle, centre: [1.2, 0.0], radius: 0.6, period: 10.0}"


@pytest.mark.parametrize(
    ("trajectory", "backend", "pattern"),
    [
        (CIRCLE, "{type: preview, horizon: 0}", r"horizon: .*> 0"),
        (CIRCLE, "{type: preview, horizon: .nan}", r"horizon"),
        (CIRCLE, "{type: preview, horizon: 0.01}", r"shorter than one control period"),
        (CIRCLE, "{type: preview, horizon: 1.0, coarse_step: 0.1}", r"does not divide"),
        (CIRCLE, "{type: preview, horizon: 1.0, coarse_step: 0.03}", r"not a multiple of dt"),
        (CIRCLE, "{type: preview, horizon: 1.0, knots: 3}", r"knots: 3 is below"),
        (CIRCLE, "{type: preview}\n        filters: [{type: otmm}]", r"filters: backend 'preview'"),
        (
            "{type: held_targets, targets: [[1.2, 0.5]], hold: 1.0}",
            "{type: preview, horizon: 0.5}",
            r"horizon: needs the desired path 0.5 s ahead, but trajectory 'held_targets' is causal",
        ),
    ],
)
def test_bad_input_is_one_line_exit_2(
    trajectory: str,
    backend: str,
    pattern: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    config = tmp_path / "bad.yaml"
    config.write_text(RUN.format(trajectory=trajectory, backend=backend))
    status = main(["run", str(config), "--out", str(tmp_path / "out"), "--quiet", "--no-figures"])
    err = capsys.readouterr().err.strip()
    assert status == 2
    assert len(err.splitlines()) == 1, err
    assert err.startswith("otmm-qp: error: ") and "Traceback" not in err
    assert re.search(pattern, err), err
    assert not (tmp_path / "out").exists()


# --- the two-rate scheme ---------------------------------------------------------------------


def test_two_rate_every_step_is_the_preview_backend() -> None:
    robot = _arm()
    q0 = np.array([0.3, 0.9, 0.6])
    start = robot.forward(q0)
    trajectory = CircleTrajectory(start, centre=start - [0.3, 0.0], radius=0.3, period=2.0)
    one, _ = _run(robot, trajectory, q0, PreviewBackend(horizon=0.4), duration=0.5)
    two, _ = _run(robot, trajectory, q0, TwoRatePreviewBackend(every=1, horizon=0.4), duration=0.5)
    np.testing.assert_allclose(two.qdot, one.qdot, atol=1e-9)


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), every=st.integers(2, 6), speed=st.floats(0.3, 2.0))
def test_two_rate_keeps_every_limit_and_tracks(seed: int, every: int, speed: float) -> None:
    rng = np.random.default_rng(seed)
    q0 = rng.uniform(-1.0, 1.0, size=3)
    room = rng.uniform(0.05, 0.5, size=(2, 3))
    limits = [[q - a, q + b] for q, a, b in zip(q0, room[0], room[1], strict=True)]
    robot = PlanarArm([1.0, 0.8, 0.5], limits=limits, velocity_limits=[speed] * 3)
    start = robot.forward(q0)
    trajectory = CircleTrajectory(start, centre=start - [0.2, 0.0], radius=0.2, period=1.5)
    backend = TwoRatePreviewBackend(every=every, horizon=0.3, infeasible_policy="hold")
    result, metrics = _run(robot, trajectory, q0, backend, duration=0.6)
    assert result.error_message is None
    assert metrics["position_violations"] == 0 and metrics["velocity_violations"] == 0


def test_two_rate_tracks_between_preview_solves() -> None:
    robot = _arm()
    q0 = np.array([0.3, 0.9, 0.6])
    start = robot.forward(q0)
    trajectory = CircleTrajectory(start, centre=start - [0.3, 0.0], radius=0.3, period=2.0)
    backend = TwoRatePreviewBackend(every=5, horizon=0.5, sliced=False)
    _, metrics = _run(robot, trajectory, q0, backend, 2.0)
    # [m] on a 0.3 m circle in 2 s (the largest error is the start from rest)
    assert metrics["rms_error"] < 1e-3 and metrics["max_error"] < 1e-2


def test_sliced_two_rate_tracks_as_the_whole_qp_does() -> None:
    # Planning from the predicted switch state keeps the plan's latency out of the tracking:
    # the sliced scheme tracks as closely as the whole QP solved every N steps.
    robot = _arm()
    q0 = np.array([0.3, 0.9, 0.6])
    start = robot.forward(q0)
    trajectory = CircleTrajectory(start, centre=start - [0.3, 0.0], radius=0.3, period=2.0)
    errors = {}
    for sliced in (False, True):
        backend = TwoRatePreviewBackend(every=10, horizon=0.5, sliced=sliced)
        result, metrics = _run(robot, trajectory, q0, backend, 2.0)
        assert result.error_message is None
        errors[sliced] = metrics["rms_error"]
    assert errors[True] < 1.2 * errors[False], errors


def test_sliced_two_rate_bounds_the_work_of_a_step() -> None:
    # After the first step, a control step runs the tracker and at most one slice of the
    # preview QP: at most KNOTS_PER_SLICE knots' kinematics (+ the tracker's target and the
    # predicted state) and at most one of the QP's factorisations or solver calls.
    robot = _arm()
    q0 = np.array([0.3, 0.9, 0.6])
    start = robot.forward(q0)
    trajectory = CircleTrajectory(start, centre=start - [0.3, 0.0], radius=0.3, period=2.0)
    backend = TwoRatePreviewBackend(every=10, horizon=1.0, knots=24, fine_steps=4)
    counts = collections.Counter()

    def counted(name, function):  # type: ignore[no-untyped-def]
        def call(*args, **kwargs):  # type: ignore[no-untyped-def]
            counts[name] += 1
            return function(*args, **kwargs)

        return call

    kinematics = robot.kinematics
    robot.kinematics = counted("kinematics", kinematics)  # type: ignore[method-assign]
    controller = Controller("two_rate", [], backend)
    controller.bind(robot, 0.01, trajectory)
    backend.reset()
    qp = backend._qp
    qp.with_active_bounds = counted("qp", qp.with_active_bounds)  # type: ignore[method-assign]
    session = backend.session
    session.load = counted("qp", session.load)  # type: ignore[method-assign]
    session.solve = counted("qp", session.solve)  # type: ignore[method-assign]
    q, qdot = q0.copy(), np.zeros(3)
    worst = collections.Counter()
    for k in range(80):
        counts.clear()
        state = KinematicState.compute(robot, q)
        counts.clear()
        qdot = controller.step(state, trajectory.sample(k * 0.01)[1], qdot).qdot
        q = q + 0.01 * qdot
        if k:
            for name, count in counts.items():
                worst[name] = max(worst[name], count)
    assert worst["qp"] == 1
    assert 2 < worst["kinematics"] <= KNOTS_PER_SLICE + 2


def test_two_rate_refuses_a_bad_rate() -> None:
    with pytest.raises(ConfigError, match="every"):
        registry.create(registry.BACKENDS, "preview_two_rate", {"every": 0}, "backend")


# --- the study's information column ---------------------------------------------------------


#: A tiny study mixing information classes: one causal row, one preview row, its causal twin.
TINY_STUDY = {
    "name": "preview-tiny",
    "seed": 3,
    "dt": 0.05,
    "duration": {"extra": 0.1},
    "robots": [{"name": "planar2", "robot": {"type": "planar", "link_lengths": [1.0, 0.8]}}],
    "generators": [{"type": "near_singular", "count": 1, "duration": [0.5, 0.6]}],
    "controllers": [
        {"name": "dls", "backend": {"type": "dls", "damping": 0.05}},
        {"name": "preview", "backend": {"type": "preview", "horizon": 0.5}},
        {"name": "causal", "backend": {"type": "preview_causal", "horizon": 0.5}},
    ],
}


def test_study_rows_record_their_information_class(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import yaml

    from otmm_qp.studies.storage import read_episodes

    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(TINY_STUDY))
    out = tmp_path / "out"
    args = ["study", str(path), "--out", str(out), "--workers", "1", "--quiet", "--no-report"]
    assert main(args) == 0
    table = read_episodes(out)
    assert table is not None
    classes = {row["controller"]: row["information"] for row in table.to_pylist()}
    assert classes == {
        "dls": "causal",
        "preview": "preview 0.5 s",
        "causal": "causal",
        "oracle": "offline",
    }
    # The README's verdict command on such a folder (its reduced run).
    capsys.readouterr()
    assert main(["study", "verdict", str(out), "--ours", "preview", "--kinds"]) == 0
    assert "`preview`" in capsys.readouterr().out


def test_the_study_report_labels_rows_by_information_class_when_it_mixes_them(
    tmp_path: Path,
) -> None:
    """Success tables and the fronts summary name each row's class; one class: no label."""
    import yaml

    from otmm_qp.studies.document import to_markdown
    from otmm_qp.studies.fronts import summary_table
    from otmm_qp.studies.report.tables import success_table
    from otmm_qp.studies.rows import Rows, load_rows
    from otmm_qp.studies.verdicts import study_fronts

    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(TINY_STUDY))
    out = tmp_path / "out"
    assert main(["study", str(path), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    report = (out / "study_report.md").read_text(encoding="utf-8")
    names = [line.split(" | ")[0] for line in report.splitlines() if line.startswith("| ")]
    for label in ("dls (causal)", "preview (preview 0.5 s)", "causal (causal)"):
        assert f"| {label}" in names, label  # every success table
    assert "| oracle (offline)" in names
    fronts = next(line for line in report.splitlines() if line.startswith("| planar2 | "))
    assert "preview (preview 0.5 s)" in fronts and "dls (causal)" in fronts, fronts
    # A study whose controller rows share one class reads as it did before the column.
    _, rows = load_rows(out)
    causal = Rows([r for r in rows.rows if r["controller"] != "preview"])
    unlabelled = Rows([{k: v for k, v in r.items() if k != "information"} for r in causal.rows])
    assert causal.information_labels() == {} == unlabelled.information_labels()
    for robot in (None, "planar2"):
        assert success_table(causal, robot) == success_table(unlabelled, robot)
    assert "(causal)" not in to_markdown([success_table(causal, None)[0]])
    fronts_of = study_fronts(causal)
    assert summary_table(fronts_of, information=causal.information_labels()) == summary_table(
        study_fronts(unlabelled)
    )


def test_the_shipped_preview_study_is_valid() -> None:
    from otmm_qp.studies.spec import load_study, plan_study

    path = Path(__file__).parents[3] / "configs" / "studies" / "preview.yaml"
    plan = plan_study(load_study(path), "preview.yaml")
    names = {controller.name for controller in plan.controllers}
    horizons = {f"preview[horizon={h:g}]" for h in (0.25, 0.5, 1, 2, 4)}
    assert horizons | {"preview_causal", "preview-smooth[smoothness=0.01]"} <= names
    assert len(plan.episodes) == 3 * 80 * (16 + 1)  # 3 robots x 80 tasks x (16 rows + oracle)
    reduced = plan_study(load_study(path.with_name("preview_crossings.yaml")), "reduced")
    assert {c.name for c in reduced.controllers} == names
    assert len(reduced.episodes) == 2 * 32 * (16 + 1)


@pytest.mark.parametrize("arm", ["ur5", "panda"])
def test_the_per_arm_crossing_studies_judge_one_preview_row(arm: str) -> None:
    # >= 60 crossing tasks per arm needs 84 tasks (every joint path and about half of the
    # near-singular passes cross); ONE preview row, so its criterion is against the field.
    from otmm_qp.studies.spec import load_study, plan_study

    path = Path(__file__).parents[3] / "configs" / "studies" / f"preview_crossings_{arm}.yaml"
    plan = plan_study(load_study(path), path.name)
    previews = [c for c in plan.controllers if c.name.startswith("preview")]
    assert [c.name for c in previews] == ["preview-minmax"]
    assert len(plan.controllers) == 9
    assert len(plan.episodes) == 84 * (9 + 1)  # tasks x (rows + oracle)
    # the same row on both arms
    assert "horizon: 1.0, peak: 0.003, peak_jump: 0.03}" in path.read_text(encoding="utf-8")


@pytest.mark.parametrize("backend", ["preview", "preview_causal", "preview_two_rate"])
def test_preview_backends_pass_conformance(backend: str) -> None:
    """The paper's E1–E3 (planar arms without speed limits, E2 starts singular) and the arms."""
    from otmm_qp.testing import conformance

    for name, verdicts in conformance.conformance_report(
        conformance.ControllerSpec(backend)
    ).items():
        failed = [v for v in verdicts if not v.passed]
        assert failed == [], (name, failed)


@pytest.mark.parametrize(
    ("backend", "sliced"),
    [(PreviewBackend, None), (TwoRatePreviewBackend, False), (TwoRatePreviewBackend, True)],
)
def test_an_acceleration_limit_bounds_every_executed_velocity_change(
    backend: type, sliced: bool | None
) -> None:
    robot = _arm()
    q0 = np.array([0.3, 0.9, 0.6])
    start = robot.forward(q0)
    trajectory = CircleTrajectory(start, centre=start - [0.3, 0.0], radius=0.3, period=2.0)
    a_max = 4.0  # [rad/s²]
    limits = [{"type": "position", "gain": 0.5}, {"type": "acceleration", "a_max": a_max}]
    extra = {} if sliced is None else {"sliced": sliced}
    tested = backend(horizon=0.5, limits=limits, infeasible_policy="hold", **extra)
    result, metrics = _run(robot, trajectory, q0, tested, 1.0)
    assert result.error_message is None
    changes = np.abs(np.diff(np.vstack([np.zeros(3), result.qdot]), axis=0))
    kept = result.status != Status.RELAXED
    assert np.all(changes[kept] <= a_max * DT * (1 + 1e-9) + 1e-12)
    # From rest onto a circle at 0.94 m/s with 4 rad/s²: it lags at first, less than qp.
    _, one_step = _run(
        robot, trajectory, q0, QpBackend(limits=limits, infeasible_policy="hold"), 1.0
    )
    if not sliced:
        assert metrics["rms_error"] < one_step["rms_error"]
    else:  # every command is the one-step tracker's: through the start it lags as qp does
        assert metrics["rms_error"] < 1.1 * one_step["rms_error"]
