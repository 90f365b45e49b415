"""Issue 11's floors, asserted as paper-style claims from real runs of configs/strategies/."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from otmm_qp.config import load_config
from otmm_qp.metrics import MetricSettings
from otmm_qp.runner import prepare_experiment, run_experiment

STRATEGIES = Path(__file__).parents[2] / "configs" / "strategies"
Runs = dict[tuple[str, str, str], dict[str, object]]


def run_subset(name: str, experiments: set[str], controllers: set[str]) -> Runs:
    suite = load_config(STRATEGIES / name)
    settings = MetricSettings(**suite.metrics.model_dump())
    out: Runs = {}
    for index, experiment in enumerate(suite.experiments):
        if experiment.name not in experiments:
            continue
        prepared = prepare_experiment(suite, index, name)
        kept = [c for c in prepared.controllers if c.name in controllers]
        prepared = dataclasses.replace(prepared, controllers=kept)
        for record in run_experiment(prepared, settings):
            r = record.result
            out[(r.experiment, r.loop_mode, r.controller)] = record.metrics
    return out


@pytest.fixture(scope="module")
def paper() -> Runs:
    return run_subset("paper.yaml", {"E1", "E2"}, {"OTMM-cbrt", "OTMM-bounded", "OTMM-directional"})


@pytest.fixture(scope="module")
def arms() -> Runs:
    return run_subset(
        "arms.yaml",
        {"ur5_wrist_pose", "ur5_elbow_pose", "ur5_elbow_position", "ur5_elbow_beyond_pose"},
        {"OTMM-linear", "OTMM-cbrt", "OTMM-bounded", "OTMM-directional"},
    )


def value(runs: Runs, experiment: str, mode: str, controller: str, metric: str) -> float:
    return float(runs[(experiment, mode, controller)][metric])  # type: ignore[arg-type]


@pytest.mark.parametrize("mode", ["feedforward", "clik", "newton"])
def test_bounded_gain_removes_the_e2_spike(paper: Runs, mode: str) -> None:
    """cbrt spikes to 37–51 rad/s from the singular start; the gain cap keeps ≤ 1.5 rad/s."""
    assert value(paper, "E2", mode, "OTMM-cbrt", "max_joint_speed") > 10.0
    assert value(paper, "E2", mode, "OTMM-bounded", "max_joint_speed") <= 1.5  # ≈ 0.72


def test_bounded_gain_keeps_cbrt_window_error_on_e1(paper: Runs) -> None:
    cbrt = value(paper, "E1", "clik", "OTMM-cbrt", "max_error_window")  # ≈ 2.33e-4 m
    bounded = value(paper, "E1", "clik", "OTMM-bounded", "max_error_window")  # ≈ 2.38e-4 m
    assert bounded <= 1.5 * cbrt


@pytest.mark.parametrize("mode", ["feedforward", "clik", "newton"])
def test_direction_aware_leaves_the_e2_singularity_unhindered(paper: Runs, mode: str) -> None:
    """Leaving σ = 0 the direction-aware filter only caps the gain: same run as bounded p."""
    directional = value(paper, "E2", mode, "OTMM-directional", "max_error_window")
    assert directional <= value(paper, "E2", mode, "OTMM-bounded", "max_error_window") * 1.0001
    assert value(paper, "E2", mode, "OTMM-directional", "max_joint_speed") <= 1.5


def test_ur5_wrist_crossing_direction_aware_peak(arms: Runs) -> None:
    """Direction-aware OTMM + pinv ≤ 0.5 rad/s (≈ 0.28) and no wrist-flip jump; the bounded p
    alone does not reach the floor (≈ 0.62 rad/s, a 1.1 rad/s flip at θ5 = 0)."""
    run = ("ur5_wrist_pose", "clik", "OTMM-directional")
    assert value(arms, *run, "max_joint_speed") <= 0.5
    assert value(arms, *run, "max_jump") <= 0.05
    assert value(arms, "ur5_wrist_pose", "clik", "OTMM-bounded", "max_joint_speed") > 0.5
    assert value(arms, "ur5_wrist_pose", "clik", "OTMM-cbrt", "max_joint_speed") > 5.0


@pytest.mark.parametrize("experiment", ["ur5_elbow_pose", "ur5_elbow_position"])
def test_ur5_elbow_otmm_jump(arms: Runs, experiment: str) -> None:
    for controller in ["OTMM-linear", "OTMM-cbrt", "OTMM-bounded", "OTMM-directional"]:
        assert value(arms, experiment, "clik", controller, "max_jump") <= 1.0, controller


def test_beyond_reach_direction_aware_settles(arms: Runs) -> None:
    """Past the reach plain OTMM chatters (jumps ≈ 32 rad/s); the direction-aware one settles."""
    run = ("ur5_elbow_beyond_pose", "clik")
    assert value(arms, *run, "OTMM-linear", "max_jump") > 10.0
    assert value(arms, *run, "OTMM-directional", "max_jump") <= 1.0  # ≈ 0.27
    assert value(arms, *run, "OTMM-directional", "final_error") < 0.11  # at the boundary
