"""OTMM+QP on every real-arm scenario: no limit violation, no blow-up, bounded joint speed."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from otmm_qp.config import load_config
from otmm_qp.metrics import MetricSettings
from otmm_qp.runner import prepare_experiment, run_experiment

ARMS = sorted((Path(__file__).parents[2] / "configs" / "arms").glob("*.yaml"))
#: Stated bound on OTMM+QP joint speed [rad/s]: the slowest arm's speed limit used here (Panda).
SPEED_BOUND = 2.62


@pytest.fixture(scope="module")
def arm_runs() -> dict[str, dict[str, dict[str, object]]]:
    """Metrics of the otmm+qp and pinv runs of every arm experiment."""
    results: dict[str, dict[str, dict[str, object]]] = {}
    for path in ARMS:
        suite = load_config(path)
        for index, experiment in enumerate(suite.experiments):
            prepared = prepare_experiment(suite, index, path.name)
            prepared = dataclasses.replace(
                prepared,
                controllers=[c for c in prepared.controllers if c.name in ("otmm+qp", "pinv")],
            )
            settings = MetricSettings(**suite.metrics.model_dump())
            records = run_experiment(prepared, settings)
            results[experiment.name] = {r.result.controller: r.metrics for r in records}
    return results


def test_every_arm_scenario_ran(arm_runs: dict[str, dict[str, dict[str, object]]]) -> None:
    assert len(arm_runs) >= 5
    assert all("otmm+qp" in runs for runs in arm_runs.values())


def test_otmm_qp_is_safe_on_every_arm_scenario(
    arm_runs: dict[str, dict[str, dict[str, object]]],
) -> None:
    for experiment, runs in arm_runs.items():
        m = runs["otmm+qp"]
        assert m["position_violations"] == 0, experiment
        assert m["velocity_violations"] == 0, experiment
        assert not m["blow_up"], experiment
        assert float(m["max_joint_speed"]) <= SPEED_BOUND, experiment  # type: ignore[arg-type]
        assert m["status_infeasible"] == 0 and m["status_nonfinite"] == 0, experiment


def test_scenarios_really_approach_singularities(
    arm_runs: dict[str, dict[str, dict[str, object]]],
) -> None:
    """Unfiltered pinv sees σ_min below 1e-2 in the singular scenarios (all but joint limits)."""
    singular = [e for e in arm_runs if "limit" not in e]
    assert len(singular) >= 4
    lows = [float(arm_runs[e]["pinv"]["min_sigma"]) for e in singular]  # type: ignore[arg-type]
    assert np.median(lows) < 1e-2, lows


def test_pinv_blows_up_at_the_ur5_wrist(arm_runs: dict[str, dict[str, dict[str, object]]]) -> None:
    assert arm_runs["ur5_wrist_pose"]["pinv"]["blow_up"]
    assert not arm_runs["ur5_wrist_pose"]["otmm+qp"]["blow_up"]
