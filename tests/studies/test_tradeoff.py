"""The offline optimum under the calm row's speeds (otmm_qp.studies.tradeoff)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from otmm_qp.cli import main as study_main
from otmm_qp.studies.execute import run_study
from otmm_qp.studies.rows import load_rows
from otmm_qp.studies.spec import parse_study, plan_study
from otmm_qp.studies.tradeoff import OUTCOMES, bounded_optimum, rebuild_task
from tests.factories import DLS_ROW, PINV_ROW, reference_study

STUDY = reference_study(
    "tradeoff",
    seed=3,
    chunk_size=4,
    generators=[
        {"type": "near_singular", "count": 4, "distance": [0.0, 0.1], "duration": [1.0, 1.5]},
        {"type": "beyond_reach", "count": 3, "duration": [1.0, 1.5]},
    ],
    controllers=[
        PINV_ROW,
        DLS_ROW,
        {"name": "jparse", "backend": {"type": "jparse"}},
        {
            "name": "OTMM-directional+pinv",
            "filters": [{"type": "otmm_directional"}],
            "backend": {"type": "pinv"},
        },
    ],
)
#: Speeds are compared with the solver's step bound, |q_{k+1} − q_k| ≤ v·dt [rad/s].
SPEED_TOL = 1e-6
#: The solver's optimality tolerance on max errors [m] (a local method).
ERROR_TOL = 1e-6


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("tradeoff")
    run_study(plan_study(parse_study(STUDY)), out, "tradeoff.yaml", workers=1)
    return out


def test_the_command_prints_the_table(study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert study_main(["study", "tradeoff", str(study)]) == 0
    text = capsys.readouterr().out
    assert text.startswith("| robot | group | calm row | accurate row | tasks |")
    body = [line for line in text.splitlines() if line.startswith("| planar2 |")]
    assert body and {line.split(" | ")[1] for line in body} <= {"near_singular", "beyond_reach"}
    assert all(line.rstrip(" |").rsplit("| ", 1)[-1] in OUTCOMES for line in body)
    assert "Evidence, not a proof" in text and "ignores one-step jumps" in text
    assert "Errors below 0.0002 m" in text  # 1 % of success.max_position_error = 0.02 m
    argv = ["study", "tradeoff", str(study), "--group-by", "kind", "--calm", "dls"]
    assert study_main([*argv, "--accurate", "pinv"]) == 0
    text = capsys.readouterr().out
    assert "| dls | pinv |" in text
    argv = ["study", "tradeoff", str(study), "--calm", "dls", "--accurate", "pinv", "--tasks", "1"]
    assert study_main(argv) == 0
    rows = [r for r in capsys.readouterr().out.splitlines() if r.startswith("| planar2 |")]
    assert rows and all(r.split(" | ")[4] == "1" for r in rows)


def test_rebuilt_task_is_the_studys(study: Path) -> None:
    # The study's own speed cap (success.max_joint_speed = 10) rebuilds its stored task: the
    # same certified lower bound (it depends on the task alone), and an upper bound no better
    # than the stored one (which also had the controllers' paths as candidates) beyond 1e-6.
    config, rows = load_rows(study)
    for row in rows.select(controller="oracle"):
        robot, weight, task, duration = rebuild_task(config, row)
        result = bounded_optimum(config, robot, weight, task, duration, 10.0)
        assert result.bracket.lower == row["reference.lower"]
        assert result.merit >= row["reference.upper"] - 1e-6 * max(1.0, row["reference.upper"])
        assert result.max_joint_speed <= 10.0


def test_bound_is_respected_and_error_is_monotone(study: Path) -> None:
    # A near-singular crossing of the non-redundant planar2: its exact path needs speed, so
    # lower caps must cost accuracy; the optimum never exceeds its cap.
    config, rows = load_rows(study)
    row = max(
        [
            r
            for r in rows.select(controller="oracle", generator="near_singular")
            if r["reference.status"] == "achievable"
        ],
        key=lambda r: r["reference.max_joint_speed"],
    )
    robot, weight, task, duration = rebuild_task(config, row)
    free = bounded_optimum(config, robot, weight, task, duration, 1e3)
    need = free.max_joint_speed
    assert need > 0.1 and free.max_error < 1e-3
    errors = []
    for cap in (need, need / 2, need / 4):
        result = bounded_optimum(config, robot, weight, task, duration, cap)
        steps = np.abs(np.diff(result.path, axis=0)) / config.dt
        assert result.max_joint_speed <= cap + SPEED_TOL
        assert float(np.max(steps)) <= cap + SPEED_TOL
        assert np.all(np.isfinite(result.path))
        errors.append(result.max_error)
    assert errors[0] >= free.max_error - ERROR_TOL
    assert errors[1] >= errors[0] - ERROR_TOL and errors[2] >= errors[1] - ERROR_TOL
    assert errors[2] > free.max_error + 1e-3  # a quarter of the speed really costs accuracy


@pytest.mark.parametrize(
    ("argv", "start"),
    [
        (["--calm", "nope"], "otmm-qp: error: --calm: no online row 'nope' in the study; have:"),
        (["--accurate", "oracle"], "otmm-qp: error: --accurate: no online row 'oracle'"),
        (["--calm", "dls", "--accurate", "dls"], "otmm-qp: error: --accurate: 'dls' is"),
        (["--tasks", "0"], "otmm-qp: error: --tasks: must be an integer >= 1, got 0"),
        (["--tasks", "x"], "otmm-qp: error: --tasks: must be an integer >= 1, got 'x'"),
        (["--group-by", "robot"], "otmm-qp: error: --group-by: 'robot' is not one of"),
        (["--bogus"], "otmm-qp: error: unrecognized arguments: --bogus"),
    ],
)
def test_bad_options_are_one_line(
    study: Path, argv: list[str], start: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert study_main(["study", "tradeoff", str(study), *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(start) and "\n" not in err and "Traceback" not in err


def test_bad_folders_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert study_main(["study", "tradeoff", str(tmp_path)]) == 2  # not a study folder
    err = capsys.readouterr().err.strip()
    assert err.startswith("otmm-qp: error:") and "\n" not in err and "Traceback" not in err
    bare = {
        **STUDY,
        "name": "bare",
        "reference": {"enabled": False},
        "generators": [{"type": "beyond_reach", "count": 1, "duration": [1.0, 1.0]}],
    }
    run_study(plan_study(parse_study(bare)), tmp_path / "bare", "bare.yaml", workers=1)
    assert study_main(["study", "tradeoff", str(tmp_path / "bare")]) == 2
    err = capsys.readouterr().err.strip()
    assert (
        err == "otmm-qp: error: study: no offline reference rows stored (reference.enabled: true)"
    )
