"""Limits as objects: each box formula, intersection and priority relaxation (properties over
random boxes), the one YAML form and the older keys mapped onto it (bit-identical runs), the
errors, and the worked example of docs/architecture.md (a braking-distance limit, one class)."""

from __future__ import annotations

from importlib import metadata

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from otmm_qp import registry
from otmm_qp.controller import Controller
from otmm_qp.exceptions import ConfigError, InfeasibleProblem, ParameterError
from otmm_qp.limits import (
    AccelerationLimit,
    Box,
    LimitBox,
    PositionLimit,
    PredictedPositionLimit,
    SingularityBarrier,
    VelocityLimit,
    conflict,
    intersect,
    make_limits,
    relaxed,
)
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.state import KinematicState
from otmm_qp_controllers.qp import QpBackend, QpStep
from otmm_qp_controllers.qp.scaled import ScaledQpBackend
from otmm_qp_controllers.sns import SnsBackend
from tests.braking_limit import BrakingDistanceLimit
from tests.test_plugins import patch_entry_points

DT = 0.01  # [s]
ARM = PlanarArm([1.0, 0.8, 0.6], limits=[[-2.5, 2.5]] * 3, velocity_limits=[2.0, 1.5, 1.0])


def test_each_box_is_its_formula() -> None:
    theta, prev = np.array([2.4, -0.3, 0.0]), np.array([0.5, -1.0, 0.2])
    out = Box(np.empty(3), np.empty(3))
    velocity = VelocityLimit(max_speed=1.2)
    velocity.bind(ARM, DT)
    velocity.compute_box(theta, prev, out)
    np.testing.assert_array_equal(out.upper, [1.2, 1.2, 1.0])
    np.testing.assert_array_equal(out.lower, -out.upper)
    position = PositionLimit(gain=0.3)
    position.bind(ARM, DT)
    position.compute_box(theta, prev, out)
    np.testing.assert_array_equal(out.lower, (0.3 / DT) * (-2.5 - theta))
    np.testing.assert_array_equal(out.upper, (0.3 / DT) * (2.5 - theta))
    acceleration = AccelerationLimit(a_max=[10.0, 20.0, 30.0])
    acceleration.bind(ARM, DT)
    acceleration.compute_box(theta, prev, out)
    np.testing.assert_array_equal(out.lower, prev - np.array([0.1, 0.2, 0.3]))
    np.testing.assert_array_equal(out.upper, prev + np.array([0.1, 0.2, 0.3]))
    unlimited = PositionLimit()
    unlimited.bind(PlanarArm([1.0, 1.0]), DT)
    unlimited.compute_box(np.zeros(2), np.zeros(2), Box(out.lower[:2], out.upper[:2]))
    assert np.all(out.lower[:2] == -np.inf) and np.all(out.upper[:2] == np.inf)  # never NaN


boxes = st.lists(st.tuples(st.floats(-5, 5), st.floats(0, 5)), min_size=3, max_size=3).map(
    lambda pairs: Box(np.array([c - h for c, h in pairs]), np.array([c + h for c, h in pairs]))
)


@given(st.lists(boxes, min_size=1, max_size=4))
def test_intersection_and_priority_relaxation(parts: list[Box]) -> None:
    """The relaxed box is never empty, keeps the first box, and is the intersection if any."""
    out = intersect(parts, Box(np.empty(3), np.empty(3)))
    np.testing.assert_array_equal(out.lower, np.maximum.reduce([b.lower for b in parts]))
    np.testing.assert_array_equal(out.upper, np.minimum.reduce([b.upper for b in parts]))
    lower, upper = relaxed(parts)
    assert np.all(lower <= upper)
    assert np.all(lower >= parts[0].lower) and np.all(upper <= parts[0].upper)  # priority 0 kept
    feasible = out.lower <= out.upper
    np.testing.assert_array_equal(lower[feasible], out.lower[feasible])
    np.testing.assert_array_equal(upper[feasible], out.upper[feasible])
    if len(parts) == 2:  # a clash shrinks to the point of the first box nearest to the second
        clash = ~feasible
        target = np.where(parts[1].upper < parts[0].lower, parts[1].upper, parts[1].lower)
        nearest = np.clip(target, parts[0].lower, parts[0].upper)
        np.testing.assert_array_equal(lower[clash], nearest[clash])


def test_limit_box_keeps_priority_order_and_names_the_conflict() -> None:
    box = LimitBox([AccelerationLimit(1.0), PositionLimit(0.5), VelocityLimit()])
    assert [limit.name for limit in box.limits] == ["velocity", "position", "acceleration"]
    box.bind(ARM, DT)
    theta = np.array([2.9, 0.0, 0.0])  # 0.4 rad beyond θ_max: position box [-270, -20] rad/s
    assert box.compute(theta, np.zeros(3))
    line = box.conflict(ARM.joint_names)
    assert line.startswith("joint 'joint1': velocity box [-2, 2], position box [-270, -20], ")
    assert line.endswith("acceleration box [-0.01, 0.01] do not intersect")
    lower, upper = box.relaxed()  # back at full speed: acceleration (priority 2) given up
    assert lower[0] == upper[0] == -2.0
    assert conflict([("a", Box(np.zeros(1), np.ones(1)))], Box(np.ones(1), np.zeros(1)), ())
    assert "#0" in conflict([], Box(np.ones(1), np.zeros(1)), ())


def test_the_limits_order_does_not_change_the_run() -> None:
    """Boxes intersect: listing the limits in another order gives the same run, bit for bit."""
    old = QpBackend(
        limits=[{"type": "position", "gain": 0.3}, {"type": "acceleration", "a_max": 20.0}],
        infeasible_policy="hold",
    )
    new = QpBackend(
        limits=[
            {"type": "acceleration", "a_max": 20.0},
            {"type": "position", "gain": 0.3},
        ],
        infeasible_policy="hold",
    )
    assert [type(limit) for limit in old.limits.boxes] == [
        VelocityLimit, PositionLimit, AccelerationLimit,
    ]  # fmt: skip
    runs = []
    for backend in (old, new):
        controller = Controller("qp", [], backend)
        controller.bind(ARM, DT)
        q, prev, qdots = np.array([2.3, 0.4, -0.2]), np.zeros(3), []
        for _ in range(60):
            state = KinematicState.compute(ARM, q)
            out = controller.step(state, np.array([3.0, -2.0]), prev)
            qdots.append(out.qdot)
            q, prev = q + DT * out.qdot, out.qdot
        runs.append(np.array(qdots))
    np.testing.assert_array_equal(runs[0], runs[1])
    barrier = make_limits([{"type": "singularity_barrier", "sigma_safe": 0.01}])
    assert isinstance(barrier.rows[0], SingularityBarrier) and barrier.rows[0].sigma_safe == 0.01
    default = make_limits(None, default_gain=1.0)
    assert [type(limit) for limit in default.boxes] == [VelocityLimit, PredictedPositionLimit]
    assert default.boxes[1].gain == 1.0  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    ("backend", "key", "value", "write"),
    [
        ("qp", "limit_gain", 0.3, "limits: [{type: position, gain: 0.3}]"),
        (
            "qp",
            "acceleration_limit",
            20.0,
            "limits: [{type: position, gain: 0.5}, {type: acceleration, a_max: 20.0}]",
        ),
        ("qp_scaled", "limit_gain", 0.3, "limits: [{type: position, gain: 0.3}]"),
        ("qp_manipulability", "acceleration_limit", 20.0, "{type: acceleration, a_max: 20.0}]"),
        ("pink", "limit_gain", 0.3, "limits: [{type: position, gain: 0.3}]"),
        (
            "sns",
            "max_speed",
            1.0,
            "limits: [{type: velocity, max_speed: 1.0}, {type: position, gain: 1.0}]",
        ),
    ],
)
def test_older_keys_are_refused_saying_what_to_write(
    backend: str, key: str, value: float, write: str
) -> None:
    """The refusal names the key and the list to write, with the user's own value."""
    with pytest.raises(ParameterError) as info:
        registry.create(registry.BACKENDS, backend, {key: value}, "backend")
    message = str(info.value)
    assert message.startswith(f"backend.{key}: removed (limits have one form: ")
    assert write in message and "\n" not in message


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: QpBackend(limits={"type": "position"}), "limits: must be a list of"),
        (lambda: QpBackend(limits=[{"gain": 0.5}]), "limits.0: must be a mapping {type: NAME"),
        (
            lambda: QpBackend(limits=[{"type": "jerk"}]),
            "limits.0: unknown limit 'jerk'; available: acceleration, command, fr3_velocity,",
        ),
        (lambda: QpBackend(limits=[{"type": "position", "gain": 2}]), "limits.0.gain: must be in"),
        (lambda: QpBackend(limits=[{"type": "position", "g": 1}]), "limits.0.g: unknown parameter"),
        (
            lambda: QpBackend(limits=[{"type": "acceleration", "a_max": -1.0}]),
            "limits.0.a_max: must be a finite number > 0 [rad/s²]",
        ),
        (
            lambda: SnsBackend(limits=[{"type": "velocity", "max_speed": float("inf")}]),
            "limits.0.max_speed: must be a finite number > 0",
        ),
        (lambda: SnsBackend(limits=[{"type": "singularity_barrier"}]), "limits: sns takes box"),
        (lambda: ScaledQpBackend(limits=[SingularityBarrier()]), "limits: qp_scaled takes box"),
    ],
)
def test_bad_limits_are_one_line(call: object, message: str) -> None:
    with pytest.raises(ConfigError) as info:
        call()  # type: ignore[operator]
    assert str(info.value).startswith(message), str(info.value)
    assert "\n" not in str(info.value)


def test_wrong_length_a_max_fails_at_bind() -> None:
    backend = QpBackend(limits=[{"type": "acceleration", "a_max": [1.0, 2.0]}])
    with pytest.raises(Exception, match=r"a_max: expected shape \(3,\), got \(2,\)"):
        backend.bind(ARM, DT)


@pytest.mark.parametrize("make", [QpBackend, SnsBackend, ScaledQpBackend])
def test_every_backend_takes_the_same_limit_objects(make: type) -> None:
    """One cap, three backends: no step exceeds it (each meets its box)."""
    backend = make(limits=[{"type": "velocity", "max_speed": 0.3}, {"type": "position"}])
    backend.bind(ARM, DT)
    state = KinematicState.compute(ARM, np.array([0.3, 0.5, -0.4]))
    out = backend.solve(state, np.array([2.0, -1.0]), np.zeros(3))
    assert np.all(np.abs(out.qdot) <= 0.3)


# ------------------------------------------------------------------- the worked example
def braking_run(backend: QpBackend) -> tuple[np.ndarray, np.ndarray]:
    """Drive joint 1 toward θ_max = 2.5 with a far target; return θ (k, 3) and q̇ (k, 3)."""
    arm = PlanarArm([1.0, 0.8, 0.6], limits=[[-2.5, 2.5]] * 3, velocity_limits=[3.0] * 3)
    controller = Controller("braking", [], backend)
    controller.bind(arm, DT)
    q, prev, thetas, qdots = np.array([1.5, 0.3, 0.2]), np.zeros(3), [], []
    for _ in range(150):
        state = KinematicState.compute(arm, q)
        out = controller.step(state, np.array([-1.0, 1.5]), prev)  # swings joint 1 up
        thetas.append(q)
        qdots.append(out.qdot)
        q, prev = q + DT * out.qdot, out.qdot
    return np.array(thetas), np.array(qdots)


def test_braking_distance_limit_is_one_class() -> None:
    """Every step can still stop before θ_max at a_max: v²/(2a) ≤ θ_max − θ (and it binds)."""
    a_max = 4.0
    theta, qdot = braking_run(QpBackend(limits=[BrakingDistanceLimit(a_max), {"type": "position"}]))
    room = 2.5 - theta
    assert np.all(room >= 0.0)
    towards = np.maximum(qdot, 0.0)
    assert np.all(towards**2 <= 2.0 * a_max * room * (1 + 1e-9) + 1e-12)
    assert np.any(
        np.isclose(towards[:, 0] ** 2, 2.0 * a_max * room[:, 0], rtol=1e-6) & (towards[:, 0] > 0.1)
    )
    plain_theta, plain_qdot = braking_run(QpBackend())
    assert np.any(np.maximum(plain_qdot, 0.0) ** 2 > 2.0 * a_max * (2.5 - plain_theta) + 1e-6)


def test_braking_distance_limit_as_a_plugin(monkeypatch: pytest.MonkeyPatch) -> None:
    """Registered under otmm_qp.limits, it is written in YAML like the built-in ones."""
    entry = metadata.EntryPoint(
        "braking_distance", "tests.braking_limit:BrakingDistanceLimit", registry.LIMITS
    )
    patch_entry_points(monkeypatch, [entry])
    params = {"limits": [{"type": "braking_distance", "a_max": 4.0}, {"type": "position"}]}
    backend = registry.create(registry.BACKENDS, "qp", params, "backend")
    assert [limit.name for limit in backend.limits.boxes] == [
        "velocity", "braking_distance", "position",
    ]  # fmt: skip
    with pytest.raises(ConfigError, match=r"backend\.limits\.0\.a_max: must be a finite"):
        registry.create(
            registry.BACKENDS,
            "qp",
            {"limits": [{"type": "braking_distance", "a_max": 0}]},
            "backend",
        )


def test_details_record_the_box_each_step_solved() -> None:
    backend = QpBackend(limits=[BrakingDistanceLimit(4.0)], infeasible_policy="raise")
    backend.bind(ARM, DT)
    state = KinematicState.compute(ARM, np.array([2.45, 0.0, 0.0]))
    out = backend.solve(state, np.array([0.0, 3.0]), np.zeros(3))
    assert isinstance(out.details, QpStep)
    assert out.details.bounds[1, 0] == pytest.approx(np.sqrt(2 * 4.0 * 0.05))
    outside = KinematicState.compute(ARM, np.array([2.9, 0.0, 0.0]))
    raising = QpBackend(limits=[BrakingDistanceLimit(4.0), {"type": "position"}])
    raising.bind(ARM, DT)
    with pytest.raises(InfeasibleProblem, match="braking_distance box"):  # named in the line
        raising.solve(outside, np.zeros(2), np.zeros(3))


def test_parameter_errors_are_parameter_errors() -> None:
    with pytest.raises(ParameterError):
        BrakingDistanceLimit(a_max=float("nan"))


def test_architecture_doc_shows_the_example_that_is_tested() -> None:
    """docs/architecture.md prints tests/braking_limit.py's class verbatim."""
    import inspect
    from pathlib import Path

    doc = (Path(__file__).parents[2] / "docs" / "architecture.md").read_text(encoding="utf-8")
    assert f"```python\n{inspect.getsource(BrakingDistanceLimit)}```" in doc
