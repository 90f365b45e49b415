"""The qp singularity barrier: the row holds whenever feasible, σ_min stays above σ_safe."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from otmm_qp import registry
from otmm_qp.config.load import parse_config
from otmm_qp.exceptions import ConfigError, ParameterError
from otmm_qp.metrics import MetricSettings
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.runner import prepare_experiment, run_experiment
from otmm_qp.singularity import sigma_min_gradient, sigma_min_rate
from otmm_qp.state import KinematicState
from otmm_qp_controllers.qp import QpBackend, QpStep
from otmm_qp_controllers.qp.formulation import BIG
from otmm_qp_controllers.qp.solvers import solve_with_qpsolvers

DT = 0.01  # [s]
UR5 = PinocchioArm(name="ur5", task="pose")
WEIGHT = np.array([1.0, 1.0, 1.0, 0.2, 0.2, 0.2])  # as configs/arms/ur5_wrist.yaml
WRIST_CONFIG = Path(__file__).parents[3] / "configs" / "arms" / "ur5_wrist.yaml"


@pytest.mark.parametrize(
    ("option", "message"),
    [
        (
            {"sigma_safe": -0.1},
            "limits.1.sigma_safe: must be a finite number >= 0, got -0.1",
        ),
        ({"gain": 0.0}, "limits.1.gain: must be in (0, 1], got 0.0"),
        ({"gain": 1.5}, "limits.1.gain: must be in (0, 1], got 1.5"),
        ({"gain": float("nan")}, "limits.1.gain: must be in (0, 1], got nan"),
        (
            {"sigma_safe": "a"},
            "limits.1.sigma_safe: must be a finite number >= 0, got 'a'",
        ),
        ({"sigma": 0.1}, "limits.1.sigma: unknown parameter; allowed: sigma_safe, gain"),
        (
            0.02,
            "limits.1: must be a mapping {type: NAME, ...}, got 0.02",
        ),
    ],
)
def test_parameters_validated_in_one_line(option: object, message: str) -> None:
    entry = {"type": "singularity_barrier", **option} if isinstance(option, dict) else option
    with pytest.raises(ConfigError) as info:
        QpBackend(limits=[{"type": "position", "gain": 0.5}, entry])  # type: ignore[list-item]
    assert str(info.value) == message


def test_the_older_key_says_what_to_write() -> None:
    with pytest.raises(ParameterError) as info:
        registry.create(
            registry.BACKENDS, "qp", {"singularity_barrier": {"sigma_safe": 0.02}}, "backend"
        )
    assert str(info.value) == (
        "backend.singularity_barrier: removed (limits have one form: {type: singularity_barrier,"
        " …} in one limits list, replacing the default set) since schema 2 (otmm-qp 0.2): write "
        "limits: [{type: position, gain: 0.5}, {type: singularity_barrier, sigma_safe: 0.02}]"
    )


def barrier_qp(**barrier: float) -> QpBackend:
    """``qp`` with its default position limit and the singularity barrier."""
    return QpBackend(
        limits=[{"type": "position", "gain": 0.5}, {"type": "singularity_barrier", **barrier}]
    )


def wrist_run(
    backend: QpBackend, theta0: np.ndarray, steps: int = 120
) -> list[tuple[KinematicState, np.ndarray, str, np.ndarray]]:
    """CLIK toward the pose at θ5 = −0.3 (through the wrist singularity θ5 = 0)."""
    backend.bind(UR5, DT)
    goal = UR5.kinematics(UR5.configuration(np.array([0.0, -1.2, 1.5, -1.8, -0.3, 0.0])))[0]
    q, prev, records = UR5.configuration(theta0), np.zeros(6), []
    for _ in range(steps):
        state = KinematicState.compute(UR5, q, WEIGHT)
        xdot = WEIGHT * (3.0 * UR5.task_error(goal, state.x))
        out = backend.solve(state, xdot, prev)
        assert np.all(np.isfinite(out.qdot))
        assert isinstance(out.details, QpStep)
        records.append((state, out.qdot, str(out.status), np.clip(out.details.bounds, -BIG, BIG)))
        q, prev = UR5.integrate(q, out.qdot, DT), out.qdot
    return records


@pytest.mark.parametrize("gain", [1.0, 0.3])
def test_row_holds_whenever_feasible(gain: float) -> None:
    """dt·σ̇_min(q̇) ≥ −γ(σ − σ_safe) at every step where some q̇ in the box satisfies it."""
    sigma_safe = 0.02
    backend = barrier_qp(sigma_safe=sigma_safe, gain=gain)
    theta0 = np.array([0.0, -1.2, 1.5, -1.8, 0.3, 0.0])
    feasible = active = 0
    for state, qdot, status, bounds in wrist_run(backend, theta0):
        required = -gain * (state.sigma_min - sigma_safe)
        row = DT * sigma_min_gradient(UR5, state)
        reach = float(np.sum(np.maximum(row * bounds[0], row * bounds[1])))
        if reach < required:
            assert status == "relaxed"
            continue
        feasible += 1
        predicted = DT * sigma_min_rate(UR5, state, qdot)
        assert predicted >= required - 1e-9, (predicted, required)
        assert np.all(qdot >= bounds[0]) and np.all(qdot <= bounds[1])
        active += bool(abs(predicted - required) < 1e-9)
    assert feasible > 100 and active > 5  # the row was binding on a stretch of the run


def test_without_barrier_the_run_crosses_the_singularity() -> None:
    theta0 = np.array([0.0, -1.2, 1.5, -1.8, 0.3, 0.0])
    sigmas = [state.sigma_min for state, *_ in wrist_run(QpBackend(), theta0)]
    assert min(sigmas) < 1e-3  # what the barrier is there to prevent


def test_barrier_inactive_far_from_singularity_changes_nothing() -> None:
    """Small commands on a regular Panda: the row never binds and q̇ is plain qp's, bit for bit."""
    panda = PinocchioArm(name="panda", task="pose")
    plain, barrier = QpBackend(), barrier_qp(sigma_safe=0.01)
    plain.bind(panda, DT)
    barrier.bind(panda, DT)
    rng = np.random.default_rng(0)
    theta = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
    state = KinematicState.compute(panda, panda.configuration(theta))
    for _ in range(10):
        xdot = 0.05 * rng.standard_normal(6)
        a, b = plain.solve(state, xdot, np.zeros(7)), barrier.solve(state, xdot, np.zeros(7))
        np.testing.assert_array_equal(a.qdot, b.qdot)
        assert isinstance(b.details, QpStep)
        assert b.details.rows == () and a.status == b.status


def test_exactly_singular_start_is_a_normal_input() -> None:
    """From θ5 = 0 (σ_min ≈ 1e-17 < σ_safe) the barrier pushes σ_min up, never NaN."""
    backend = barrier_qp(sigma_safe=0.02)
    theta0 = np.array([0.0, -1.2, 1.5, -1.8, 0.0, 0.0])
    records = wrist_run(backend, theta0, steps=60)
    first_state, _, first_status, _ = records[0]
    assert first_state.sigma_min < 1e-12
    assert first_status in ("bounded", "relaxed")
    assert records[-1][0].sigma_min > 0.015  # pushed up toward σ_safe


def test_step_with_row_equals_pure_problem_from_scratch() -> None:
    backend = barrier_qp(sigma_safe=0.02)
    theta0 = np.array([0.0, -1.2, 1.5, -1.8, 0.3, 0.0])
    backend.bind(UR5, DT)
    checked = 0
    goal = UR5.kinematics(UR5.configuration(np.array([0.0, -1.2, 1.5, -1.8, -0.3, 0.0])))[0]
    q, prev = UR5.configuration(theta0), np.zeros(6)
    for _ in range(60):
        state = KinematicState.compute(UR5, q, WEIGHT)
        out = backend.solve(state, WEIGHT * 3.0 * UR5.task_error(goal, state.x), prev)
        assert isinstance(out.details, QpStep)
        rows = out.details.rows
        if rows and rows[0].slack == 0.0:
            problem = out.details.problem
            assert problem is not None and problem.C.shape == (1, 6)
            np.testing.assert_array_equal(problem.C[0], rows[0].row)
            expected = solve_with_qpsolvers(problem.to_qpsolvers(), "quadprog")
            assert expected is not None
            np.testing.assert_allclose(out.qdot, expected, atol=1e-8)
            checked += 1
        q, prev = UR5.integrate(q, out.qdot, DT), out.qdot
    assert checked > 0


def test_ur5_wrist_scenario_keeps_sigma_min_near_sigma_safe() -> None:
    """configs/arms/ur5_wrist.yaml with a barrier qp: plain qp reaches σ_min ≈ 6e-5, the
    barrier keeps the run's minimum σ_min within 1 % of σ_safe (first-order prediction)."""
    data = yaml.safe_load(WRIST_CONFIG.read_text())
    data["experiments"][0]["controllers"] = [
        {"name": "qp", "backend": {"type": "qp", "damping": 1.0e-3}},
        {
            "name": "qp+barrier",
            "backend": {
                "type": "qp",
                "damping": 1.0e-3,
                "limits": [
                    {"type": "position", "gain": 0.5},
                    {"type": "singularity_barrier", "sigma_safe": 0.02, "gain": 1.0},
                ],
            },
        },
    ]
    suite = parse_config(data, "ur5_wrist+barrier")
    records = run_experiment(
        prepare_experiment(suite, 0, "ur5_wrist+barrier"),
        MetricSettings(**suite.metrics.model_dump()),
    )
    metrics = {r.result.controller: r.metrics for r in records}
    assert float(metrics["qp"]["min_sigma"]) < 1e-3  # type: ignore[arg-type]
    barrier = metrics["qp+barrier"]
    assert float(barrier["min_sigma"]) >= 0.99 * 0.02  # type: ignore[arg-type]
    assert barrier["position_violations"] == 0 and barrier["velocity_violations"] == 0
    assert barrier["status_infeasible"] == 0 and not barrier["blow_up"]
