"""The command limit (acceleration and jerk of the command), composed braking first.

Hypothesis draws limits, starts (inside, at and beyond the position limits, moving fast toward
them) and commands; a step's velocity is any point of the step's box (what every box backend
returns). Asserted: the box is never empty when the hard boxes are not; it stays inside the
position and speed boxes; the rest state never passes a position limit; the acceleration box
holds on every step after the first (the claim of ``otmm_qp.limits.command_limit``), and on the
first whenever it meets the hard boxes.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp.cli import main
from otmm_qp.exceptions import OtmmError
from otmm_qp.limits import Box, CommandLimit, LimitBox, PositionLimit, PredictedPositionLimit
from otmm_qp.limits.velocity_limit import VelocityLimit
from otmm_qp.plants.declaration import PlantDeclaration, combine
from otmm_qp.robots.planar_arm import PlanarArm

RTOL = 1e-9


def _robot(lower: list[float], width: list[float], speed: list[float]) -> PlanarArm:
    limits = [[lo, lo + w] for lo, w in zip(lower, width, strict=True)]
    return PlanarArm([1.0] * len(lower), limits=limits, velocity_limits=speed)


def _box(robot: PlanarArm, dt: float, gain: float, a: float, j: float | None, predicted: bool):
    position = PredictedPositionLimit(gain) if predicted else PositionLimit(gain)
    box = LimitBox([VelocityLimit(), position, CommandLimit(acceleration=a, jerk=j)])
    box.declare_plant(PlantDeclaration())
    box.bind(robot, dt)
    box.reset()
    return box


joints = st.integers(1, 3)


@st.composite
def scenes(draw: st.DrawFn) -> dict:
    """Limits, a start inside the position limits and any previous command."""
    nv = draw(joints)
    floats = st.floats
    lower = draw(st.lists(floats(-3.0, 0.0), min_size=nv, max_size=nv))
    width = draw(st.lists(floats(0.01, 4.0), min_size=nv, max_size=nv))
    speed = draw(st.lists(floats(0.2, 5.0), min_size=nv, max_size=nv))
    fraction = draw(st.lists(floats(0.0, 1.0), min_size=nv, max_size=nv))
    previous = draw(st.lists(floats(-8.0, 8.0), min_size=nv, max_size=nv))
    return {
        "robot": _robot(lower, width, speed),
        "theta": np.array([lo + f * w for lo, f, w in zip(lower, fraction, width, strict=True)]),
        "previous": np.array(previous),
        "dt": draw(st.sampled_from([1e-3, 2e-3, 1e-2])),
        "gain": draw(floats(0.5, 1.0)),
        "a": draw(floats(1.0, 50.0)),
        "j": draw(st.one_of(st.none(), floats(500.0, 20000.0))),
        "predicted": draw(st.booleans()),
        "seed": draw(st.integers(0, 2**31 - 1)),
    }


@settings(max_examples=25, deadline=None)
@given(scenes())
def test_position_kept_and_acceleration_held_after_the_first_step(scene: dict) -> None:
    robot, dt, a = scene["robot"], scene["dt"], scene["a"]
    box = _box(robot, dt, scene["gain"], a, scene["j"], scene["predicted"])
    lower, upper = (np.asarray(x) for x in robot.position_limits)
    speed = np.asarray(robot.velocity_limits)
    theta, previous = scene["theta"].copy(), scene["previous"].copy()
    rng = np.random.default_rng(scene["seed"])
    for k in range(60):
        empty = box.compute(theta, previous)
        assert not empty  # the start is inside: the hard boxes meet
        lb, ub = box.bounds
        assert np.all(lb <= ub)
        assert np.all(ub <= speed * (1 + RTOL)) and np.all(lb >= -speed * (1 + RTOL))
        if k > 0:  # the claim: braking at a always fits, so the acceleration box holds
            assert scene["j"] is not None or not box.softened  # only the jerk box may go
            assert np.all(ub <= previous + a * dt * (1 + RTOL) + 1e-12)
            assert np.all(lb >= previous - a * dt * (1 + RTOL) - 1e-12)
        # any point of the box, often an end (pushing toward a limit as hard as allowed)
        pick = rng.choice([0.0, 1.0, rng.uniform()], size=theta.size)
        qdot = lb + pick * (ub - lb)
        theta = theta + qdot * dt
        scale = 1e-12 * (1.0 + np.abs(theta))
        assert np.all(theta <= upper + scale) and np.all(theta >= lower - scale)
        previous = qdot


@settings(max_examples=60, deadline=None)
@given(scenes(), st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3))
def test_braking_first_from_any_state(scene: dict, offset: list[float]) -> None:
    """At and beyond the limits, moving fast: the hard boxes kept, the soft ones when they fit."""
    robot, dt, a = scene["robot"], scene["dt"], scene["a"]
    nv = robot.nv
    box = _box(robot, dt, scene["gain"], a, None, False)
    lower, upper = (np.asarray(x) for x in robot.position_limits)
    theta = np.clip(scene["theta"] + np.array(offset[:nv]), lower - 0.5, upper + 0.5)
    previous = scene["previous"]
    empty = box.compute(theta, previous)
    hard = [part for limit, part in zip(box.limits, box.parts, strict=True) if not limit.soft]
    hard_lower = np.max([p.lower for p in hard], axis=0)
    hard_upper = np.min([p.upper for p in hard], axis=0)
    assert empty == bool(np.any(hard_lower > hard_upper))
    if empty:
        return  # the backend's policy answers (relaxed by priority), as without a command limit
    lb, ub = box.bounds
    assert np.all(lb <= ub)
    assert np.all(lb >= hard_lower) and np.all(ub <= hard_upper)
    fits = (previous - a * dt <= hard_upper) & (previous + a * dt >= hard_lower)
    within = (lb >= previous - a * dt * (1 + RTOL) - 1e-12) & (
        ub <= previous + a * dt * (1 + RTOL) + 1e-12
    )
    assert np.all(within[fits])
    assert box.softened == bool(np.any(~fits))
    # relaxed toward braking: the clashing joints sit on the hard end nearest the soft box
    above = ~fits & (previous - a * dt > hard_upper)
    assert np.all(lb[above] == hard_upper[above]) and np.all(ub[above] == hard_upper[above])


def test_jerk_box_is_the_second_difference() -> None:
    """J_k = 2q̇_{k−1} − q̇_{k−2} ± j dt², with q̇_{−2} = 0 on the first step."""
    robot = _robot([-10.0], [20.0], [100.0])
    dt, a, j = 0.01, 1000.0, 200.0
    box = _box(robot, dt, 1.0, a, j, False)
    box.compute(np.zeros(1), np.array([0.3]))
    assert box.bounds[0, 0] == pytest.approx(0.6 - j * dt * dt)
    assert box.bounds[1, 0] == pytest.approx(0.6 + j * dt * dt)
    box.compute(np.zeros(1), np.array([0.5]))
    assert box.bounds[0, 0] == pytest.approx(0.7 - j * dt * dt)


def test_without_a_command_limit_the_box_is_unchanged() -> None:
    """Opt-in: no command limit, no stopping bound, the position box as before."""
    robot = _robot([-1.0, -1.0], [2.0, 2.0], [1.0, 1.0])
    plain = LimitBox([VelocityLimit(), PositionLimit(0.5)])
    plain.bind(robot, 0.01)
    theta = np.array([0.99, -0.5])
    plain.compute(theta, np.zeros(2))
    rate = 0.5 / 0.01
    expected_upper = np.minimum(1.0, (np.array([1.0, 1.0]) - theta) * rate)
    expected_lower = np.maximum(-1.0, (np.array([-1.0, -1.0]) - theta) * rate)
    assert np.array_equal(plain.bounds, [expected_lower, expected_upper])  # bit for bit
    assert not plain.softened


@pytest.mark.parametrize(
    ("params", "field"),
    [
        ({"acceleration": -1.0}, "acceleration"),
        ({"acceleration": math.nan}, "acceleration"),
        ({"acceleration": 5.0, "jerk": 0.0}, "jerk"),
        ({"acceleration": [1.0, math.nan]}, "acceleration"),
        ({"acceleration": 5.0, "stopping": 1}, "stopping"),
    ],
)
def test_bad_parameters_name_the_field(params: dict, field: str) -> None:
    with pytest.raises(OtmmError, match=field):
        CommandLimit(**params)


def test_plant_thresholds_and_their_absence() -> None:
    robot = _robot([-1.0, -1.0], [2.0, 2.0], [1.0, 1.0])
    declared = combine(
        [PlantDeclaration(interface_acceleration=(10.0,), interface_jerk=(5000.0, 4000.0))]
    )
    limit = CommandLimit()
    limit.declare_plant(declared)
    acceleration, jerk = limit.limits(2)
    assert acceleration.tolist() == [10.0, 10.0] and jerk is not None
    assert jerk.tolist() == [5000.0, 4000.0]
    limit.declare_plant(PlantDeclaration())  # nothing declared: no box, no stopping distance
    limit.bind(robot, 0.01)
    assert not limit.active and limit.braking is None
    with pytest.raises(OtmmError, match="jerk: needs an acceleration limit"):
        CommandLimit(jerk=100.0).limits(2)
    wrong = CommandLimit(acceleration=[1.0, 2.0, 3.0])
    with pytest.raises(OtmmError, match="acceleration"):
        wrong.bind(robot, 0.01)


LOOP = {
    "name": "command-loop",
    "dt": 0.02,
    "experiments": [
        {
            "name": "e",
            "robot": {
                "type": "planar",
                "link_lengths": [1.0, 0.8, 0.5],
                "limits": [[-2.0, 2.0], [-2.5, 2.5], [-1.0, 1.0]],
                "velocity_limits": [2.0, 2.0, 2.0],
            },
            "q0": [0.3, 0.4, 0.2],
            "trajectory": {"type": "circle", "centre": [1.0, 0.5], "radius": 0.9, "period": 1.5},
            "duration": 1.5,
            "plant": [{"type": "interface", "acceleration": 5.0, "jerk": 500.0}],
            "controllers": [
                {"name": name + suffix, "backend": dict(backend, **extra)}
                for name, backend, gain in (
                    ("qp", {"type": "qp"}, 0.5),
                    ("qp_scaled", {"type": "qp_scaled"}, 0.5),
                    ("sns", {"type": "sns"}, 1.0),
                    (
                        "preview",
                        {"type": "preview", "horizon": 0.2, "knots": 4, "fine_steps": 2},
                        0.5,
                    ),
                )
                for suffix, extra in (
                    ("", {}),
                    (
                        "-cmd",
                        {
                            "limits": [
                                {"type": "predicted_position", "gain": gain},
                                {"type": "command"},
                            ]
                        },
                    ),
                )
            ],
        }
    ],
}


def test_the_loop_keeps_the_interface_thresholds_and_the_limits(tmp_path: Path) -> None:
    """Every box backend with the command limit: no step over the interface's thresholds,
    none past a position limit, no infeasible step; without it the stream passes them."""
    config = tmp_path / "config.yaml"
    config.write_text(yaml.safe_dump(LOOP), encoding="utf-8")
    assert (
        main(["run", str(config), "--out", str(tmp_path / "out"), "--no-figures", "--quiet"]) == 0
    )
    with (tmp_path / "out" / "summary.csv").open(encoding="utf-8") as handle:
        rows = {row["controller"]: row for row in csv.DictReader(handle)}
    for name in ("qp", "qp_scaled", "sns", "preview"):
        limited, free = rows[f"{name}-cmd"], rows[name]
        assert limited["completed"] == "True" and int(limited["status_infeasible"]) == 0
        assert int(limited["command_acceleration_violations"]) == 0
        assert int(limited["command_jerk_violations"]) == 0
        assert int(limited["position_violations"]) == 0
        assert float(limited["max_command_acceleration"]) <= 5.0 * (1 + 1e-9)
        assert int(free["command_acceleration_violations"]) > 0  # the test can fail


def test_fr3_velocity_box_is_libfrankas() -> None:
    """Far from the limits the cap minus kLimitEps; at θ⁺ (θ⁻) the joint must move back."""
    from otmm_qp.limits.fr3_velocity_limit import FR3_VELOCITY, LIMIT_EPS, Fr3VelocityLimit

    speed, _, _, upper, lower = (np.array(c) for c in zip(*FR3_VELOCITY, strict=True))
    robot = _robot([-10.0] * 7, [20.0] * 7, [10.0] * 7)
    limit = Fr3VelocityLimit()
    limit.bind(robot, 0.001)
    box = Box(np.empty(7), np.empty(7))
    limit.compute_box((upper + lower) / 2.0, np.zeros(7), box)
    assert np.allclose(box.upper, speed - LIMIT_EPS) and np.allclose(box.lower, LIMIT_EPS - speed)
    limit.compute_box(upper, np.zeros(7), box)
    assert np.allclose(box.upper, -LIMIT_EPS)
    limit.compute_box(lower, np.zeros(7), box)
    assert np.allclose(box.lower, LIMIT_EPS)
    # monotone: the upper bound falls as θ approaches θ⁺
    previous = box.upper.copy()
    for fraction in np.linspace(0.0, 1.0, 11):
        limit.compute_box(lower + fraction * (upper - lower), np.zeros(7), box)
        assert np.all(box.upper <= previous + 1e-12) or fraction == 0.0
        previous = box.upper.copy()
    with pytest.raises(OtmmError, match="7-joint"):
        limit.bind(_robot([-1.0] * 3, [2.0] * 3, [1.0] * 3), 0.001)


def test_pair_cost_counts_aborts_and_pairs_the_tasks() -> None:
    """--pair: aborts and limit violations per row, McNemar's discordant tasks, one-line error."""
    from otmm_qp.studies.plant_headline import pair_cost

    def row(name: str, task: int, success: bool, jerk: int, error: float) -> dict:
        return {
            "controller": name, "robot": "r", "generator": "g", "task_index": task,
            "success": success, "max_error": error, "position_violations": 0,
            "command_acceleration_violations": 0, "command_jerk_violations": jerk,
        }  # fmt: skip

    rows = [row("new@p", t, t != 0, int(t == 1), 0.1 * t) for t in range(4)]
    rows += [row("old@q", t, t != 3, 0, 0.1 * t + 0.05) for t in range(4)]
    table = pair_cost(rows, [("new@p", "old@q")])
    line = table.splitlines()[-1]
    cells = [c.strip() for c in line.strip("|").split("|")]
    assert cells[0] == "new@p / old@q" and cells[1] == "4"
    assert cells[2] == "1 / 0"  # one episode of new would be aborted
    assert cells[4] == "75 / 75" and cells[5].startswith("1 / 1,")
    assert cells[6].startswith("4 / 0 / 0,")  # new's error lower on every task
    with pytest.raises(OtmmError, match="--pair"):
        pair_cost(rows, [("new@p", "missing@q")])


@settings(max_examples=10, deadline=None)
@given(
    st.lists(st.floats(-3.0, 0.0), min_size=2, max_size=2),
    st.lists(st.floats(1.0, 4.0), min_size=2, max_size=2),
    st.lists(st.floats(0.5, 3.0), min_size=2, max_size=2),
    st.lists(st.floats(0.05, 0.95), min_size=2, max_size=2),
    st.integers(0, 2**31 - 1),
)
def test_with_the_jerk_limited_brake_the_acceleration_box_and_the_limits_hold(
    lower: list[float], width: list[float], speed: list[float], start: list[float], seed: int
) -> None:
    """The FCI's thresholds at 50 Hz (1 ms interface), from rest, any point of the box
    commanded: no step's box is empty, the acceleration box holds on every step and no joint
    passes its limits (the jerk-limited stopping distance and the jerk box are soft: given up
    where they must be, which this test does not bound)."""
    robot = _robot(lower, width, speed)
    dt, a, j = 0.02, 7.5, 3750.0
    box = LimitBox([VelocityLimit(), PredictedPositionLimit(0.5), CommandLimit()])
    box.declare_plant(
        PlantDeclaration(interface_acceleration=(a,), interface_jerk=(j,), interface_period=1e-3)
    )
    box.bind(robot, dt)
    box.reset()
    low, high = (np.asarray(x) for x in robot.position_limits)
    theta = low + np.array(start) * (high - low)
    previous = np.zeros(2)
    rng = np.random.default_rng(seed)
    for _ in range(60):
        assert not box.compute(theta, previous)
        lb, ub = box.bounds
        qdot = lb + rng.choice([0.0, 1.0, rng.uniform()], size=2) * (ub - lb)
        assert np.all(np.abs(qdot - previous) <= a * dt * (1 + RTOL) + 1e-12)
        theta = theta + qdot * dt
        assert np.all(theta <= high + 1e-12) and np.all(theta >= low - 1e-12)
        previous = qdot
