"""Plant stages: ideal, lag, delay, sensor, their composition, and the MuJoCo body."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from otmm_qp import registry
from otmm_qp.exceptions import ConfigError, ParameterError
from otmm_qp.plants import PlantChain, build_plant
from otmm_qp.robots.planar_arm import PlanarArm

DT = 0.01


def planar() -> PlanarArm:
    return PlanarArm([1.0, 0.8, 0.5])


def commands(steps: int, nv: int, seed: int = 3) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.normal(0.0, 0.2, (steps, nv)), axis=0)


def run(plant: PlantChain, robot: PlanarArm, qdots: np.ndarray) -> np.ndarray:
    q = np.array([0.3, -0.4, 0.5])
    plant.reset(robot, q, DT)
    out = [q]
    for qdot in qdots:
        q = plant.advance(q, qdot).q
        out.append(q)
    return np.array(out)


def test_registered_through_entry_points() -> None:
    assert {"ideal", "lag", "delay", "sensor", "mujoco"} <= set(registry.available(registry.PLANTS))
    assert build_plant(None).label() == "ideal"
    assert build_plant({"type": "ideal"}).ideal


def test_ideal_is_the_euler_integrator_bit_for_bit() -> None:
    robot, qdots = planar(), commands(50, 3)
    q = np.array([0.3, -0.4, 0.5])
    expected = [q]
    for qdot in qdots:
        q = robot.integrate(q, qdot, DT)
        expected.append(q)
    assert np.array_equal(run(build_plant({"type": "ideal"}), robot, qdots), np.array(expected))


def test_delay_zero_is_ideal_and_delay_n_shifts_the_command() -> None:
    robot, qdots = planar(), commands(40, 3)
    ideal = run(build_plant(None), robot, qdots)
    assert np.array_equal(run(build_plant({"type": "delay", "steps": 0}), robot, qdots), ideal)
    late = run(build_plant({"type": "delay", "steps": 2}), robot, qdots)
    shifted = run(build_plant(None), robot, np.vstack([np.zeros((2, 3)), qdots[:-2]]))
    assert np.array_equal(late, shifted)


@pytest.mark.parametrize("update", ["exact", "euler"])
def test_lag_converges_to_ideal_as_tau_shrinks(update: str) -> None:
    robot, qdots = planar(), commands(60, 3)
    ideal = run(build_plant(None), robot, qdots)
    taus = [0.05, 0.02, 0.01] if update == "euler" else [0.05, 0.01, 1e-3, 1e-5]
    gaps = [
        float(
            np.max(
                np.abs(
                    run(build_plant({"type": "lag", "tau": t, "update": update}), robot, qdots)
                    - ideal
                )
            )
        )
        for t in taus
    ]
    assert all(b < a for a, b in zip(gaps, gaps[1:], strict=False))  # strictly decreasing
    assert gaps[-1] < (1e-12 if update == "euler" else 1e-5)  # euler at tau = dt: alpha = 1


def test_lag_is_the_first_order_response() -> None:
    robot = planar()
    plant = build_plant({"type": "lag", "tau": 0.05})
    plant.reset(robot, np.zeros(3), DT)
    q = np.zeros(3)
    for k in range(1, 30):
        step = plant.advance(q, np.ones(3))
        q = step.q
        assert step.qdot == pytest.approx(np.full(3, 1.0 - math.exp(-k * DT / 0.05)), rel=1e-12)


def test_sensor_noise_is_seeded_and_metrics_see_the_truth() -> None:
    robot = planar()
    q = np.array([0.3, -0.4, 0.5])
    views = []
    for _ in range(2):
        plant = build_plant({"type": "sensor", "noise": 1e-3, "seed": 7})
        plant.reset(robot, q, DT)
        views.append([plant.measure(q) for _ in range(20)])
    assert np.array_equal(np.array(views[0]), np.array(views[1]))
    noise = np.array(views[0]) - q
    assert 3e-4 < float(np.std(noise)) < 3e-3
    other = build_plant({"type": "sensor", "noise": 1e-3, "seed": 8})
    other.reset(robot, q, DT)
    assert not np.array_equal(other.measure(q), views[0][0])
    assert not plant.exact_measurement


@given(st.floats(-3.0, 3.0), st.integers(16, 1 << 20))
def test_quantisation_is_within_half_a_count(angle: float, counts: int) -> None:
    robot = PlanarArm([1.0])
    plant = build_plant({"type": "sensor", "counts": counts})
    plant.reset(robot, np.zeros(1), DT)
    seen = plant.measure(np.array([angle]))
    quantum = 2.0 * math.pi / counts
    assert abs(seen[0] - angle) <= quantum / 2.0 + 1e-12
    assert abs(seen[0] / quantum - round(seen[0] / quantum)) < 1e-6


def test_composition_order_and_one_body() -> None:
    plant = build_plant([{"type": "lag", "tau": 0.02}, {"type": "delay", "steps": 1}])
    assert plant.label() == "lag(tau=0.02)+delay(steps=1)"
    assert [s.name for s in plant.stages] == ["lag", "delay", "ideal"]
    with pytest.raises(ConfigError, match="at most one body"):
        build_plant([{"type": "ideal"}, {"type": "ideal"}])


@pytest.mark.parametrize(
    ("spec", "field"),
    [
        ({"type": "lag", "tau": 0.0}, "plant.tau"),
        ({"type": "lag", "tau": -1.0}, "plant.tau"),
        ({"type": "delay", "steps": -1}, "plant.steps"),
        ({"type": "delay", "steps": 1.5}, "plant.steps"),
        ({"type": "sensor", "noise": float("nan")}, "plant.noise"),
        ({"type": "sensor", "counts": 0}, "plant.counts"),
        ({"type": "mujoco", "frequency": float("inf")}, "plant.frequency"),
        ({"type": "mujoco", "armature": -0.1}, "plant.armature"),
        ({"type": "mujoco", "armature": float("nan")}, "plant.armature"),
        ({"type": "mujoco", "armature": [0.1, float("inf")]}, "plant.armature"),
        ({"type": "mujoco", "contacts": 1}, "plant.contacts"),
        ({"type": "warp"}, "plant"),
        ({"type": "lag", "tau": 0.1, "tua": 1}, "plant.tua"),
    ],
)
def test_bad_parameters_are_one_line_naming_the_field(spec: dict[str, object], field: str) -> None:
    with pytest.raises(ConfigError) as info:
        build_plant(spec)
    assert str(info.value).startswith(field + ":")
    assert "\n" not in str(info.value)


def test_euler_lag_refuses_tau_below_dt() -> None:
    plant = build_plant({"type": "lag", "tau": 0.005, "update": "euler"})
    with pytest.raises(ParameterError, match="tau: with update: euler"):
        plant.reset(planar(), np.zeros(3), DT)
