"""Study report with synthetic oracle rows (the data contract), criteria and drill-down."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from otmm_qp.cli import main
from otmm_qp.config.load import load_config
from otmm_qp.metrics.metrics import METRIC_NAMES
from otmm_qp.runner.run import run_suite
from otmm_qp.studies.criteria import failure_causes, speed_ratios
from otmm_qp.studies.episodes import TIMING_METRICS
from otmm_qp.studies.execute import run_study
from otmm_qp.studies.report import write_study_report
from otmm_qp.studies.report.lines import verdict_line
from otmm_qp.studies.rows import RELATIVE_ERROR, load_rows
from otmm_qp.studies.schema import SuccessCriteria
from otmm_qp.studies.spec import parse_study, plan_study
from otmm_qp.studies.storage import read_episodes
from otmm_qp.studies.verdicts import TaskGroup
from tests.factories import LOOSE_SUCCESS, tiny_study

# The real reference is off: the fixture ``with_oracle`` adds synthetic reference rows whose
# values are known (the real one is tested in test_reference*.py and test_readme_numbers.py).
STUDY = tiny_study(
    "drill",
    seed=5,
    chunk_size=2,
    time_series={"tasks": 0},
    reference={"enabled": False},
    success=LOOSE_SUCCESS,
    generators=[
        {"type": "near_singular", "count": 3, "duration": [1.0, 1.5]},
        {"type": "beyond_reach", "count": 2, "duration": [1.0, 1.5]},
    ],
)


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("drill")
    run_study(plan_study(parse_study(STUDY)), out, "drill", workers=1)
    return out


def _oracle_rows(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One synthetic reference row per task, following the oracle/stats contract."""
    out = []
    tasks = {}
    for row in rows:
        tasks.setdefault((row["generator"], row["task_index"]), row)
    for (generator, index), row in sorted(tasks.items()):
        beyond = generator == "beyond_reach"
        best = 0.3 if beyond else 1e-4
        out.append(
            {
                **{k: row[k] for k in ("study", "robot", "generator", "generator_params")},
                "task_index": index,
                "task_seed": row["task_seed"],
                "episode_key": f"{'f' * 20}{len(out):012d}",
                "controller": "oracle",
                "backend": "oracle",
                "filters": "none",
                "loop_mode": "offline",
                "status": "ok",
                "completed": True,
                "max_error": best,
                "final_error": 1e-4,
                "max_joint_speed": 0.5,
                "reference.status": "unachievable" if beyond else "achievable",
                "reference.upper": 5.0 if beyond else 0.5,
                "reference.lower": 4.0 if beyond else 0.0,
                "reference.max_error": best,
                "reference.max_orientation_error": math.nan,
                "reference.max_joint_speed": 0.5,
                "reference.touches_position_limit": index == 0,
                "reference.min_sigma": 1e-3 if not beyond else 0.5,
                "reference.near_singular": not beyond,
                "reference.achievable": not beyond,
            }
        )
    return out


def _task_id(row: dict[str, Any]) -> str:
    position = 0 if row["generator"] == "near_singular" else 1
    return f"{row['robot']}/{row['generator']}#{position}/{row['task_index']}"


@pytest.fixture(scope="module")
def with_oracle(study: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A copy of the study with task_id on every row and one oracle row per task."""
    out = tmp_path_factory.mktemp("with-oracle")
    table = read_episodes(study)
    assert table is not None
    rows = table.to_pylist()
    oracle = _oracle_rows(rows)
    marker = json.loads((study / "study.json").read_text())
    if isinstance(marker.get("episode_keys"), list):  # the oracle rows are part of the plan
        marker["episode_keys"] += [r["episode_key"] for r in oracle]
    (out / "study.json").write_text(json.dumps(marker))
    for row in rows + oracle:
        row["task_id"] = _task_id(row)
    (out / "episodes").mkdir()
    pq.write_table(pa.Table.from_pylist(rows), out / "episodes" / "part-0.parquet")
    pq.write_table(pa.Table.from_pylist(oracle), out / "episodes" / "part-1.parquet")
    return out


def test_oracle_rows_are_the_reference_never_a_competitor(with_oracle: Path) -> None:
    config, rows = load_rows(with_oracle)
    assert rows.controllers() == ["pinv", "dls"]
    assert rows.has_reference
    for row in rows.rows:
        if row["controller"] == "oracle":
            continue
        expected = row["max_error"] - row["reference.max_error"]
        if row["kept_limits"]:
            assert row[RELATIVE_ERROR] == pytest.approx(expected)
        else:  # a row that broke a limit has no yardstick within the limits
            assert row[RELATIVE_ERROR] is None and row["failure_causes"]
        assert row["reference.achievable"] == (row["generator"] != "beyond_reach")
    write_study_report(with_oracle)
    report = (with_oracle / "study_report.md").read_text()
    verdict = report[report.index("### Verdict") : report.index("### Failure causes")]
    assert "**Singular crossings** (3 tasks" in verdict
    assert "**Unachievable (certified)** (2 tasks" in verdict
    assert "**Undecided** (0 tasks" in verdict
    bracket = report[report.index("### Reference bracket") : report.index("### Pareto fronts")]
    assert "| unachievable (certified) | 2 | 0/2/0/0 | 1 | 1 |" in bracket
    assert "| all tasks | 5 | 3/2/0/0 | 0.5 | 1 |" in bracket
    assert "**Limit-bound motion** (2 tasks" in verdict  # task 0 of each generator
    assert "oracle-relative" in verdict
    # the oracle is a row of the table, never in a paired test or ranking
    assert "| oracle | 5 | 0 | reference (not ranked) |" in report
    paired = report[report.index("### Paired success") : report.index("## All robots")]
    assert "| oracle |" not in paired
    assert (
        "Ranking by success rate" in report
        and "oracle" not in report.split("Ranking by success rate")[1].split("\n")[0]
    )
    html = (with_oracle / "study_report.html").read_text()
    assert "data:image/png;base64," in html and '<div class="verdict">' in html
    assert "<script" not in html


def test_graceful_criteria_judge_unachievable_tasks(with_oracle: Path) -> None:
    config, rows = load_rows(with_oracle)
    criteria = config.success
    for row in rows.select(generator="beyond_reach"):
        if row["controller"] == "oracle":
            continue
        bound = criteria.graceful.error_factor * row["reference.max_error"]
        fails_error = "error" in row["failure_causes"]
        final_bound = max(criteria.max_position_error or 0.0, 1.5 * 1e-4)
        assert fails_error == (row["max_error"] > bound or row["final_error"] > final_bound)


def test_failure_causes_split_limit_and_speed_and_error() -> None:
    criteria = SuccessCriteria(max_position_error=0.01)
    base = {"status": "ok", "completed": True, "max_error": 0.001, "max_speed_ratio": 0.5}
    assert failure_causes(base, criteria) == ()
    assert failure_causes({**base, "max_speed_ratio": 1.2}, criteria) == ("speed",)
    assert failure_causes({**base, "position_violations": 3}, criteria) == ("position_limit",)
    assert failure_causes({**base, "max_error": 0.5, "blow_up": True}, criteria) == (
        "error",
        "blow_up",
    )
    assert failure_causes({**base, "completed": False}, criteria) == ("stuck",)
    assert failure_causes({"status": "error"}, criteria) == ("run_error",)
    absolute = SuccessCriteria(max_joint_speed=3.0)  # replaces the per-joint bound
    assert failure_causes({**base, "max_speed_ratio": 2.0, "max_joint_speed": 2.9}, absolute) == ()
    unachievable = {**base, "reference.achievable": False, "reference.max_error": 0.2}
    assert failure_causes({**unachievable, "max_error": 0.29}, criteria) == ()
    assert failure_causes({**unachievable, "max_error": 0.31}, criteria) == ("error",)
    assert failure_causes({**unachievable, "max_error": 0.25, "max_jump_ratio": 0.9}, criteria) == (
        "chatter",
    )


def test_speed_ratio_is_per_joint_against_the_robot_limits() -> None:
    class Run:
        qdot = np.array([[9.0, 0.0], [1.0, -3.0], [0.5, 1.0]])  # step 0 (from rest) excluded
        velocity_limits = np.array([2.0, np.inf])

    ratios = speed_ratios(Run())  # type: ignore[arg-type]
    assert ratios["max_speed_ratio"] == pytest.approx(0.5)  # joint 1: 1/2; joint 2: unlimited
    assert ratios["max_jump_ratio"] == pytest.approx(4.0)  # |1 - 9| / 2


def test_every_row_has_a_stable_short_id_shown_next_to_the_worst(study: Path) -> None:
    _, rows = load_rows(study)
    ids = [r["episode_id"] for r in rows.rows]
    assert len(set(ids)) == len(ids)
    assert all(r["episode_key"].startswith(r["episode_id"]) for r in rows.rows)
    write_study_report(study)
    report = (study / "study_report.md").read_text()
    worst = report[report.index("### Worst episode") :]
    assert any(f"`{i}`" in worst for i in ids)


def _summary_row(folder: Path) -> dict[str, str]:
    with (folder / "summary.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 1
    return rows[0]


@pytest.mark.parametrize("generator", ["near_singular", "beyond_reach"])
def test_show_writes_a_config_that_reproduces_the_episode(
    study: Path, generator: str, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    _, rows = load_rows(study)
    row = next(r for r in rows.select(generator=generator, controller="dls"))
    assert main(["study", "show", str(study), "--episode", row["episode_id"]]) == 0
    printed = capsys.readouterr().out
    assert row["episode_id"] in printed and "run config:" in printed
    config = study / "drilldown" / f"episode-{row['episode_id']}.yaml"
    text = config.read_text()
    if generator == "beyond_reach":  # (a near-singular path may graze the boundary too)
        assert "out_of_reach: true" in text
    # the API run of the written config: every stored metric, bit for bit
    suite = load_config(config)
    metrics = run_suite(suite, None, progress=None).records[0].metrics
    compared = [n for n in METRIC_NAMES if n not in TIMING_METRICS]
    for name in compared:
        stored, again = row[name], metrics[name]
        same = stored == again or (
            isinstance(stored, float) and math.isnan(stored) and math.isnan(float(again))
        )
        assert same, (name, stored, again)
    # and the CLI: ``otmm-qp run`` then ``otmm-qp replay`` on its folder
    run_out = tmp_path / "rerun"
    assert main(["run", str(config), "--out", str(run_out), "--figures", "none", "--quiet"]) == 0
    assert float(_summary_row(run_out)["max_error"]) == pytest.approx(row["max_error"], rel=1e-8)
    assert main(["replay", str(run_out)]) == 0


def test_unknown_episode_is_one_line_exit_2(
    study: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["study", "show", str(study), "--episode", "0123456789"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "no episode '0123456789'" in err
    assert main(["study", "show", str(study), "--episode", "xyz"]) == 2
    assert "not an episode id" in capsys.readouterr().err


def _synthetic(name: str, index: int, success: bool) -> dict[str, Any]:
    return {
        "controller": name,
        "robot": "r",
        "generator": "g",
        "generator_params": "{}",
        "task_index": index,
        "loop_mode": "clik",
        "success": success,
    }


def test_group_verdict_names_the_pick_and_its_paired_evidence() -> None:
    rows = [_synthetic("a", i, True) for i in range(30)]
    rows += [_synthetic("b", i, i < 5) for i in range(30)]
    rows += [_synthetic("c", i, i != 0) for i in range(30)]
    text = verdict_line(TaskGroup("singular crossings", "test tasks", rows))
    # a does not beat c: it leads, it is no pick (never bold when undecided)
    assert "leader a (success 100 %; not a decision: it does not beat every other" in text
    assert "**a**" not in text
    assert "not separated from it by the paired test: c (97 %)" in text
    assert "the closest b (17 %: a alone succeeds on 25 tasks, b alone on 0" in text
    two = [r for r in rows if r["controller"] != "c"]
    assert "pick **a** (success 100 %)" in verdict_line(TaskGroup("k", "test tasks", two))
    for row in two:  # a breaks the arm's limits on most of its tasks: said, never bold
        if row["controller"] == "a" and row["task_index"] < 20:
            row["failure_causes"] = ["speed"]
    text = verdict_line(TaskGroup("k", "test tasks", two))
    assert "**a**" not in text and "breaks the arm's limits on 20 of 30 episodes" in text
    tied = [_synthetic(n, i, i % 2 == 0) for n in "xy" for i in range(10)]
    text = verdict_line(TaskGroup("beyond-reach motion", "test tasks", tied))
    assert "no paired test separates the controllers" in text and "pick" not in text
    assert "needs about" in text or "succeed on the same tasks" in text  # never a bare "none"
