import numpy as np
import pytest

from otmm_qp.metrics import MetricSettings, compute_metrics
from otmm_qp.simulation import RunResult


def synthetic(
    qdot: np.ndarray, q: np.ndarray | None = None, sigma: np.ndarray | None = None
) -> RunResult:
    steps, nv = qdot.shape
    dt = 0.1
    return RunResult(
        experiment="x",
        controller="c",
        loop_mode="clik",
        dt=dt,
        joint_names=tuple(f"j{i}" for i in range(nv)),
        task_kind="position",
        t=np.arange(steps) * dt,
        q=np.zeros((steps, nv)) if q is None else q,
        qdot=qdot,
        position=np.zeros((steps, 2)),
        position_desired=np.zeros((steps, 2)),
        error=np.tile([0.3, 0.4], (steps, 1)),
        sigma_min=np.linspace(1.0, 0.0, steps) if sigma is None else sigma,
        p=np.zeros(steps),
        filter_active=np.zeros(steps, dtype=bool),
        removed=np.zeros(steps),
        damping=np.full(steps, np.nan),
        scale=np.ones(steps),
        weak_speed=np.zeros(steps),
        status=np.array(["ok"] * steps, dtype=object),
        step_time=np.full(steps, 2e-6),
        position_limits=(np.full(nv, -1.0), np.full(nv, 1.0)),
        velocity_limits=np.full(nv, 2.0),
    )


def test_speed_jump_and_chattering_definitions() -> None:
    qdot = np.array([[1.0, 0.0], [1.5, 0.0], [0.5, 0.2], [0.5, 0.2]])
    m = compute_metrics(synthetic(qdot))
    assert m["initial_jump"] == 1.0  # from rest
    assert m["max_joint_speed"] == 1.5  # steps 1.. only
    assert m["chattering"] == pytest.approx(0.5 + (1.0 + 0.2))  # Σ_k≥1 ‖Δq̇‖₁
    assert m["max_jump"] == pytest.approx(1.0)
    assert m["accel_sign_changes"] == 1  # joint 0: +, − ; joint 1: +
    assert m["max_error"] == pytest.approx(0.5) and m["rms_error"] == pytest.approx(0.5)


def test_limit_violations_and_blow_up() -> None:
    qdot = np.array([[0.0], [3.0], [0.5]])
    q = np.array([[0.0], [1.2], [-1.5]])
    m = compute_metrics(synthetic(qdot, q=q), MetricSettings(blow_up_speed=2.5))
    assert m["position_violations"] == 2 and m["max_position_excess"] == pytest.approx(0.5)
    assert m["velocity_violations"] == 1 and m["max_velocity_excess"] == pytest.approx(1.0)
    assert m["blow_up"] is True
    assert (
        compute_metrics(synthetic(qdot, q=q), MetricSettings(blow_up_speed=5))["blow_up"] is False
    )


def test_singular_window_is_centred_on_the_sigma_minimum() -> None:
    steps = 21
    sigma = np.abs(np.arange(steps) - 10) / 10.0  # minimum at t = 1.0 s
    run = synthetic(np.zeros((steps, 1)), sigma=sigma)
    run.error[10] = [3.0, 4.0]
    m = compute_metrics(run, MetricSettings(window=0.4, sigma_s=0.25))
    assert m["t_min_sigma"] == pytest.approx(1.0) and m["min_sigma"] == 0.0
    assert m["max_error_window"] == pytest.approx(5.0)
    assert m["steps_below_sigma_s"] == 5  # σ ∈ {0, 0.1, 0.2} → 5 steps
