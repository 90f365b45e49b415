"""The shipped study files are valid and as large as promised; the study benchmark runs."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from otmm_qp.studies.spec import load_study, plan_study
from tests.factories import load_script

ROOT = Path(__file__).resolve().parents[2]
STUDIES = ROOT / "configs" / "studies"


def test_arms_study_has_two_thousand_tasks_and_eight_controllers() -> None:
    config = load_study(STUDIES / "arms.yaml")
    assert {r.robot.params["name"] for r in config.robots} == {"ur5", "panda"}
    assert {g.type for g in config.generators} == {
        "near_singular",
        "joint_path",
        "beyond_reach",
        "boundary",
        "random_reachable",
    }
    assert sum(g.count for g in config.generators) * len(config.robots) >= 2000
    plan = plan_study(config, "arms.yaml")
    names = [c.name for c in plan.controllers] + [n for n, _ in plan.skipped]
    assert len(names) >= 10
    assert {
        "pinv",
        "dls",
        "dls_adaptive",
        "qp",
        "OTMM+pinv[p=linear]",
        "OTMM+pinv[p=cbrt]",
        "OTMM+qp",
        "servo_scaling+qp",
        "pink",
        "oink",
    } == set(names)


def test_planar_study_is_valid() -> None:
    plan = plan_study(load_study(STUDIES / "planar.yaml"), "planar.yaml")
    assert len(plan.episodes) == 60 * (5 + 1)  # 60 tasks x (5 controllers + the oracle)


def test_bench_study_runs_tiny(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    module = load_script("benchmarks/bench_study.py")
    out = tmp_path / "bench.json"
    assert (
        module.main(["--tasks", "2", "--config", str(STUDIES / "planar.yaml"), "--json", str(out)])
        == 0
    )
    numbers = json.loads(out.read_text())
    assert numbers["episodes"] > 0 and numbers["serial_compute_s"] > 0
    assert numbers["serial_overhead"] > -1.0 and numbers["speedup"] > 0


def test_arms_study_judges_speed_by_each_robots_own_limits() -> None:
    """Issue 18: 3 rad/s was below the UR5's limits and above the Panda's."""
    success = load_study(STUDIES / "arms.yaml").success
    assert success.max_joint_speed is None and success.joint_speed_factor == 1.0
