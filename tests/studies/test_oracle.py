"""The reference in studies: one ``oracle`` row per task, ``task_id`` everywhere, never rerun."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from otmm_qp.reference import REFERENCE_COLUMNS
from otmm_qp.studies.execute import run_study
from otmm_qp.studies.spec import parse_study, plan_study
from otmm_qp.studies.storage import read_episodes
from tests.factories import load_script, reference_study

STUDY = reference_study(
    "oracle",
    seed=4,
    chunk_size=2,
    generators=[
        {"type": "beyond_reach", "count": 2, "duration": [1.0, 1.5]},
        {"type": "random_reachable", "count": 2, "duration": [1.0, 1.5]},
        {"type": "random_reachable", "count": 1, "duration": [1.0, 1.5], "name": "slow"},
    ],
    controllers=[
        {"name": "qp", "backend": {"type": "qp", "solver": "daqp"}},
        {"name": "dls", "backend": {"type": "dls"}, "grid": {"damping": [0.02, 0.05]}},
    ],
)


def _rows(out: Path) -> list[dict]:
    table = read_episodes(out)
    assert table is not None
    return table.to_pylist()


@pytest.fixture(scope="module")
def study_out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("oracle")
    plan = plan_study(parse_study(STUDY))
    outcome = run_study(plan, out, "oracle.yaml", workers=1)
    assert outcome.ran == len(plan.episodes) == 5 * (3 + 1)
    return out


def test_one_oracle_row_per_task_with_the_contract_columns(study_out: Path) -> None:
    rows = _rows(study_out)
    oracle = [r for r in rows if r["controller"] == "oracle"]
    tasks = {r["task_id"] for r in rows}
    assert len(oracle) == len(tasks) == 5
    assert {r["task_id"] for r in oracle} == tasks
    assert tasks == {
        "planar2/beyond_reach#0/0",
        "planar2/beyond_reach#0/1",
        "planar2/random_reachable#1/0",
        "planar2/random_reachable#1/1",
        "planar2/slow/0",
    }
    for row in oracle:
        assert (row["backend"], row["filters"], row["loop_mode"]) == ("oracle", "none", "offline")
        assert set(REFERENCE_COLUMNS) <= set(row)
        assert row["reference.achievable"] == (row["reference.status"] == "achievable")
        # position task: the position optimum is the best path's own error
        assert row["max_error"] == pytest.approx(row["reference.max_error"])
        assert row["reference.lower"] <= row["reference.upper"]
        assert row["position_violations"] == 0 and row["velocity_violations"] == 0
        assert row["reference.max_joint_speed"] <= 10.0
        assert math.isnan(row["reference.max_orientation_error"])  # position task
        assert row["reference.near_singular"] == (row["reference.min_sigma"] < 0.05)
    by_type = {r["generator"]: r["reference.status"] for r in oracle}
    assert by_type == {"beyond_reach": "unachievable", "random_reachable": "achievable"}
    assert all(r["generator_entry"] for r in rows)


def test_resume_does_not_recompute_the_reference(study_out: Path) -> None:
    plan = plan_study(parse_study(STUDY))
    again = run_study(plan, study_out, "oracle.yaml", workers=1)
    assert again.ran == 0 and again.skipped_stored == 20
    assert sum(r["controller"] == "oracle" for r in _rows(study_out)) == 5


def test_stored_success_is_judged_with_the_reference_also_when_it_is_stored(
    tmp_path: Path,
) -> None:
    """Controller rows are judged with their task's reference (graceful on unachievable
    tasks), as the report judges them, also in a unit whose reference row is stored already."""
    from otmm_qp.studies.episodes import run_chunk
    from otmm_qp.studies.execute import make_chunks, payload_of, stored_references
    from otmm_qp.studies.rows import load_rows
    from otmm_qp.studies.storage import study_id

    study = dict(
        STUDY,
        dt=0.02,
        success={"max_position_error": 0.02, "max_joint_speed": 100.0},
        generators=[{"type": "beyond_reach", "count": 3, "duration": [1.0, 1.5]}],
    )
    plan = plan_study(parse_study(study))
    run_study(plan, tmp_path, "graceful.yaml", workers=1)
    stored = {r["episode_key"]: bool(r["success"]) for r in _rows(tmp_path)}
    _, report = load_rows(tmp_path)
    online = [r for r in report.rows if r["controller"] != "oracle"]
    judged = {r["episode_key"]: r["success"] for r in online}
    assert {k: stored[k] for k in judged} == judged
    # Discriminating: beyond the reach the tolerance fails every episode, the graceful rule not.
    assert all(r["max_error"] > 0.02 for r in online)
    assert any(r["success"] for r in online)

    oracle_keys = {e.key for e in plan.episodes if e.is_reference}
    payload = payload_of(plan)
    ident = study_id(plan.config.model_dump(mode="json"))
    stored_refs = stored_references(plan, oracle_keys, tmp_path, ident)
    assert len(stored_refs) == 3  # every task's stored reference travels with its unit
    for references in (stored_refs, None):  # the stored one, or solved again
        rows = [
            row
            for chunk in make_chunks(plan, oracle_keys, references)  # no controller stored
            for row in run_chunk(payload, chunk).rows
        ]
        assert {r["controller"] for r in rows} == {"qp", "dls[damping=0.02]", "dls[damping=0.05]"}
        assert {r["episode_key"]: bool(r["success"]) for r in rows} == judged


def test_time_budget_keeps_the_best_path_so_far(tmp_path: Path) -> None:
    study = dict(STUDY, generators=[STUDY["generators"][0]], reference={"time_budget": 1e-9})
    plan = plan_study(parse_study(study))
    outcome = run_study(plan, tmp_path, "s", workers=1)
    assert outcome.ran == 2 * 4
    oracle = [r for r in _rows(tmp_path) if r["controller"] == "oracle"]
    assert [r["reference.status"] for r in oracle] == ["unachievable", "unachievable"]
    assert all("time budget" in r["error_message"] for r in oracle)


def test_a_failing_solve_is_a_stored_failed_reference_and_the_study_goes_on(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from otmm_qp.reference.sqp import SequentialQP, SolverFailure

    def refuse(*args: object, **kwargs: object) -> None:
        raise SolverFailure("OSQP status 'primal infeasible'")

    monkeypatch.setattr(SequentialQP, "_solve", refuse)
    study = dict(STUDY, generators=[STUDY["generators"][0]])
    plan = plan_study(parse_study(study))
    outcome = run_study(plan, tmp_path, "s", workers=1)
    assert outcome.ran == 2 * 4
    oracle = [r for r in _rows(tmp_path) if r["controller"] == "oracle"]
    assert [r["reference.status"] for r in oracle] == ["failed", "failed"]
    assert all("solver failure" in r["error_message"] for r in oracle)
    assert all(r["status"] == "ok" for r in _rows(tmp_path) if r["controller"] != "oracle")


def test_reference_can_be_switched_off() -> None:
    plan = plan_study(parse_study(dict(STUDY, reference={"enabled": False})))
    assert len(plan.episodes) == 5 * 3


@pytest.mark.parametrize(
    ("reference", "field"),
    [
        ({"time_budget": 0}, "reference.time_budget"),
        ({"time_budget": -1.0}, "reference.time_budget"),
        ({"time_budget": float("nan")}, "reference.time_budget"),
        ({"time_budget": float("inf")}, "reference.time_budget"),
        ({"speed_bound": "fast"}, "speed_bound"),
        ({"polish_iterations": -1}, "reference.polish_iterations"),
        ({"starts": 0}, "reference.starts"),
        ({"perturbations": 1.5}, "reference.perturbations"),
    ],
)
def test_bad_reference_settings_name_the_field(reference: dict, field: str) -> None:
    from otmm_qp.exceptions import ConfigError

    with pytest.raises(ConfigError, match=field):
        parse_study(dict(STUDY, reference=reference))


@pytest.mark.parametrize("budget", ["0", "-1", ".nan", ".inf"])
def test_bad_budget_is_one_line_exit_2_before_any_compute(
    tmp_path: Path, budget: str, capsys: pytest.CaptureFixture[str]
) -> None:
    import yaml

    from otmm_qp.cli import main

    text = yaml.safe_dump(STUDY).replace(
        "seed: 4", f"seed: 4\nreference: {{time_budget: {budget}}}"
    )
    study = tmp_path / "bad.yaml"
    study.write_text(text)
    out = tmp_path / "out"
    assert main(["study", str(study), "--out", str(out), "--workers", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "reference.time_budget" in err[0]
    assert not out.exists()


def _bench_reference() -> Any:
    return load_script("benchmarks/bench_reference.py")


def test_bench_reference_runs_tiny(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import json

    import yaml

    module = _bench_reference()
    config = tmp_path / "tiny.yaml"
    config.write_text(yaml.safe_dump(dict(STUDY, controllers=STUDY["controllers"][:1])))
    out = tmp_path / "bench.json"
    kept = tmp_path / "study"
    argv = ["--tasks", "3", "--config", str(config), "--json", str(out), "--check", "1"]
    assert module.main([*argv, "--out", str(kept)]) == 0
    numbers = json.loads(out.read_text())
    assert numbers["check"]["tasks"] == 1 and numbers["check"]["improved"] in (0, 1)
    check = numbers["check"]
    assert 0 <= check["improved_not_achievable"] <= min(check["not_achievable"], check["improved"])
    assert numbers["tasks"] == 3 and numbers["episodes"] == 6
    assert 0.0 < numbers["reference_s"] < numbers["compute_s"]
    assert 0.0 < numbers["reference_share"] < 1.0
    assert sum(g["tasks"] for g in numbers["groups"].values()) == 3
    assert "% (" in capsys.readouterr().out
    # the check alone, on the stored study: the same numbers (deterministic SLSQP)
    again = tmp_path / "again.json"
    assert module.main(["--stored", str(kept), "--check", "1", "--json", str(again)]) == 0
    stored = json.loads(again.read_text())
    assert stored["check"]["ratios"] == numbers["check"]["ratios"]
    assert stored["groups"] == numbers["groups"]
    assert "independent SLSQP re-solve of 1 tasks" in capsys.readouterr().out


def test_bench_reference_compares_two_studies_as_the_report_judges(
    tmp_path: Path, study_out: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--compare``: a study against itself changes nothing; against the same tasks with
    the polish and the least squares switched off, each count is what the stored rows say."""
    import json

    from otmm_qp.studies.rows import load_rows

    module = _bench_reference()
    same = module.compare(study_out, study_out)
    assert same["tasks"] == 5 and same["rows"] == 15
    assert same["success_changed"] == same["labels_changed"] == 0
    assert same["groups_changed"] == same["accuracy_changed"] == 0
    assert same["upper_moved"] == same["position_moved"] == 0
    assert same["upper_improved"] == same["position_improved"] == 0
    assert same["relative_shift_max"] == 0.0
    assert same["accuracy"] >= 1 and same["groups"] >= 3

    rough = tmp_path / "rough"
    cheap = dict(STUDY, reference={"polish_iterations": 0, "iterations": 0, "minimax_rounds": 0})
    run_study(plan_study(parse_study(cheap)), rough, "rough.yaml", workers=1)
    target = tmp_path / "compare.json"
    argv = ["--stored", str(rough), "--compare", str(study_out), "--json", str(target)]
    assert module.main(argv) == 0
    numbers = json.loads(target.read_text())["compare"]
    _, base = load_rows(study_out)
    _, other = load_rows(rough)
    status = {r["task_id"]: r["reference.status"] for r in base.rows if r["controller"] == "oracle"}
    now = {r["task_id"]: r["reference.status"] for r in other.rows if r["controller"] == "oracle"}
    assert numbers["labels_changed"] == sum(status[t] != now[t] for t in status)
    success = {(r["task_id"], r["controller"]): r["success"] for r in base.rows}
    assert numbers["success_changed"] == sum(
        bool(success[(r["task_id"], r["controller"])]) != bool(r["success"])
        for r in other.rows
        if r["controller"] != "oracle"
    )
    hard = [t for t in status if status[t] != "achievable"]
    assert numbers["not_achievable"] == len(hard)
    upper = {r["task_id"]: r["reference.upper"] for r in base.rows if r["controller"] == "oracle"}
    rough_upper = {
        r["task_id"]: r["reference.upper"] for r in other.rows if r["controller"] == "oracle"
    }
    # without the solves the pool is a subset of the full one: never a lower upper bound
    assert all(rough_upper[t] >= upper[t] for t in upper)
    assert numbers["upper_moved"] == sum(rough_upper[t] > 1.05 * upper[t] for t in hard)
    assert numbers["upper_improved"] == 0  # and so never more than 5 % lower
    reverse = module.compare(rough, study_out)  # the full solve against the rough one
    assert reverse["upper_improved"] == numbers["upper_moved"]
    assert "success changed on" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        module.main(["--tasks", "3", "--compare", str(study_out)])  # --compare needs --out
