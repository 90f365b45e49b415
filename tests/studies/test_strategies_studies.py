"""The issue-20 study files are valid, and a tiny cut of one runs through group_verdict."""

from __future__ import annotations

from pathlib import Path

import yaml

from otmm_qp.cli import main as cli
from otmm_qp.studies.execute import run_study
from otmm_qp.studies.spec import load_study, parse_study, plan_study

STUDIES = Path(__file__).resolve().parents[2] / "configs" / "studies"


def test_strategies_studies_are_valid_and_hold_our_row() -> None:
    # Controller episodes, then one offline-reference (oracle) episode per task.
    for name, episodes, tasks in (
        ("strategies_planar.yaml", 1496, 136),
        ("strategies_arms.yaml", 1920, 192),
    ):
        plan = plan_study(load_study(STUDIES / name), name)
        assert len(plan.episodes) == episodes + tasks
        assert sum(1 for e in plan.episodes if e.is_reference) == tasks
        names = [c.name for c in plan.controllers]
        assert "sigma_lm" in names and "OTMM-directional+sigma_lm" in names
        assert "held_target" in {g.type for g in load_study(STUDIES / name).generators}


def test_strategies_studies_use_the_trusted_instrument() -> None:
    arms = load_study(STUDIES / "strategies_arms.yaml")
    assert arms.reference.enabled and arms.success.max_joint_speed is None  # each joint's limit
    assert arms.success.joint_speed_factor == 1.0
    assert arms.success == load_study(STUDIES / "arms.yaml").success
    readme = load_study(STUDIES / "strategies_readme.yaml")
    assert readme.success == arms.success and readme.controllers == arms.controllers
    # planar arms have no velocity limits: an absolute bound is the only speed criterion
    planar = load_study(STUDIES / "strategies_planar.yaml")
    assert planar.reference.enabled and planar.success.max_joint_speed == 10.0


def test_a_tiny_cut_runs_and_gets_a_verdict(tmp_path: Path, capsys) -> None:
    data = yaml.safe_load((STUDIES / "strategies_planar.yaml").read_text())
    data["robots"] = data["robots"][:1]
    data["generators"] = [
        {**g, "count": 2} for g in data["generators"] if g["type"] in ("held_target", "boundary")
    ]
    data["controllers"] = [
        c for c in data["controllers"] if c["name"] in ("dls", "dls_error", "sigma_lm")
    ]
    plan = plan_study(parse_study(data))
    outcome = run_study(plan, tmp_path / "study", "tiny", workers=1)
    assert outcome.ran == 12 + 4  # 3 controllers x 4 tasks, and the 4 tasks' references
    report = tmp_path / "verdict.md"
    verdict = ["study", "verdict", str(tmp_path / "study"), "--ours"]
    assert cli([*verdict, "sigma_lm", "--out", str(report)]) == 0
    text = report.read_text()
    assert "| planar2 | held_target |" in text and "| planar2 | boundary |" in text
    assert cli([*verdict, "nope"]) == 2
    # --highlight: validated against the study's controllers before anything is computed
    capsys.readouterr()
    study = str(tmp_path / "study")
    assert cli(["report", study, "--highlight", "nope"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("otmm-qp: error: --highlight: no controller 'nope' in the study; have:")
    assert "\n" not in err and "Traceback" not in err
    assert not (tmp_path / "study" / "study_report.md").exists()
    assert cli(["report", str(tmp_path), "--highlight", "dls"]) == 2  # not a study folder
    assert "only a study folder" in capsys.readouterr().err
    file = tmp_path / "tiny.yaml"
    file.write_text(yaml.safe_dump(data))
    fresh = tmp_path / "fresh"
    assert cli(["study", str(file), "--out", str(fresh), "--highlight", "nope", "--quiet"]) == 2
    assert not fresh.exists()
    assert cli(["report", study, "--highlight", "sigma_lm"]) == 0
    text = (tmp_path / "study" / "study_report.md").read_text()
    assert "### Pareto fronts on planar2" in text and "**sigma_lm** (ours)" in text
