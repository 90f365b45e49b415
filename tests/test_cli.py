"""The CLI: bad input gives one line naming the field and exit status 2; results survive."""

from __future__ import annotations

import csv
import importlib
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from otmm_qp import registry
from otmm_qp.backends.backend import Backend, BackendOutput, truncated_pseudoinverse_apply
from otmm_qp.cli import main
from otmm_qp.exceptions import InfeasibleProblem
from otmm_qp.state import KinematicState
from tests.cli_errors import refusal_text
from tests.factories import tiny_run

RETIRED_ALIASES = (
    "otmm_qp.studies.group_verdict",
    "otmm_qp.studies.tradeoff",
    "otmm_qp.studies.plant_headline",
    "otmm_qp.output.pareto",
)

GOOD = tiny_run()

BAD = {
    "malformed YAML": (GOOD.replace("dt: 0.02", "dt: [0.02"), r"malformed YAML at line \d+"),
    "unknown key": (GOOD.replace("dt: 0.02", "dt: 0.02\nspeed: 3"), "speed: unknown key"),
    "unknown backend": (
        GOOD.replace("type: pinv", "type: pinvv"),
        "experiments.0.controllers.0.backend: unknown backend 'pinvv'; available: .*dls.*pinv",
    ),
    "unknown filter": (
        GOOD.replace("type: otmm", "type: otm"),
        "filters.0: unknown filter 'otm'; available:",
    ),
    "unknown parameter": (
        GOOD.replace("p: linear", "p: linear, gain: 2"),
        r"filters.0.gain: unknown parameter; allowed: sigma_s, p, p_params, corank",
    ),
    "q0 wrong length": (
        GOOD.replace("[0.927, -2.5]", "[0.927]"),
        r"experiments.0.q0: expected shape \(2,\), got \(1,\)",
    ),
    "sigma_s <= 0": (
        GOOD.replace("sigma_s: 0.05", "sigma_s: 0"),
        "filters.0.sigma_s: must be a finite number > 0",
    ),
    "dt <= 0": (GOOD.replace("dt: 0.02", "dt: 0"), "dt: Input should be greater than 0"),
    "negative gain": (
        GOOD.replace("dt: 0.02", "dt: 0.02\nclik_gain: -1"),
        "clik_gain: Input should be greater than or equal to 0",
    ),
    "unreachable": (
        GOOD.replace("radius: 0.6", "radius: 0.7").replace("duration: 0.4", "duration: 10"),
        r"experiments.0.trajectory: point \[1.7583, 0.4223\] at t = 3.97 s "
        "is outside the workspace of planar2",
    ),
    "bad loop mode": (
        GOOD.replace("[clik]", "[open]"),
        "loop_modes.0: Input should be 'feedforward', 'clik' or 'newton'",
    ),
    "start outside limits": (
        GOOD.replace(
            "link_lengths: [1.0, 0.8]}", "link_lengths: [1.0, 0.8], limits: [[-1, 1], [-1, 1]]}"
        ),
        r"experiments.0.q0: joint 'joint2' = -2.5 is outside its limits \[-1, 1\]",
    ),
}


ARM = """
name: arm
dt: 0.01
loop_modes: [clik]
experiments:
  - name: A
    robot: {type: pinocchio, name: ur5, task: pose}
    q0: [0.0, -1.2, 1.5, -1.8, 0.3, 0.0]
    trajectory: {type: pose_line, end: [0.5, 0.1, 0.4], duration: 1.0}
    controllers:
      - name: qp
        backend: {type: qp, solver: daqp}
"""

ARM_BAD = {
    "unknown robot": (
        ARM.replace("name: ur5", "name: ur99"),
        "experiments.0.robot: name: unknown robot .ur99.; valid names: kinova, panda, ur10, ur3",
    ),
    "missing URDF": (
        ARM.replace("name: ur5", "urdf: /nonexistent.urdf"),
        "experiments.0.robot: urdf: file not found: /nonexistent.urdf",
    ),
    "unknown frame": (
        ARM.replace("task: pose}", "task: pose, frame: nope}"),
        "experiments.0.robot: unknown frame 'nope'; valid frames: base, .*tool0",
    ),
    "unknown solver": (
        ARM.replace("solver: daqp", "solver: gurobi"),
        "experiments.0.controllers.0.backend: unknown QP solver 'gurobi'; installed: .*daqp",
    ),
    "weight shape": (
        ARM.replace("    q0:", "    task_weight: [1, 1]\n    q0:"),
        r"experiments.0.task_weight: expected shape \(6,\), got \(2,\)",
    ),
    "q0 outside limits": (
        ARM.replace("-1.8, 0.3", "-1.8, 9.3"),
        r"experiments.0.q0: joint 'wrist_2_joint' = 9.3 is outside its limits",
    ),
}

ALL_BAD = {**BAD, **{f"arm: {name}": case for name, case in ARM_BAD.items()}}


@pytest.mark.parametrize("case", list(ALL_BAD))
def test_bad_input_one_line_exit_2(
    case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text, pattern = ALL_BAD[case]
    config = tmp_path / "bad.yaml"
    config.write_text(text)
    status = main(["run", str(config), "--out", str(tmp_path / "out"), "--quiet", "--no-figures"])
    err = capsys.readouterr().err.strip()
    assert status == 2
    text = refusal_text(err)  # a first line of at most 200 characters, details after

    assert re.search(pattern, text), err
    assert not (tmp_path / "out").exists()  # rejected before any compute


def test_missing_config_file(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "/nonexistent/x.yaml"]) == 2
    assert "x.yaml: no such config file" in capsys.readouterr().err


class FailingBackend(Backend):
    """Solves like pinv for 5 steps, then reports an infeasible problem."""

    def reset(self) -> None:
        self.calls = 0

    def solve(
        self, state: KinematicState, xdot: np.ndarray, qdot_prev: np.ndarray
    ) -> BackendOutput:
        self.calls += 1
        if self.calls > 5:
            raise InfeasibleProblem(-1, "joint box is empty")
        return BackendOutput(truncated_pseudoinverse_apply(state, xdot))


def test_finished_experiments_keep_their_results(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A run stopped by an error mid-suite keeps its steps and the other runs' results; exit 2."""
    monkeypatch.setitem(registry._cache, (registry.BACKENDS, "failing"), FailingBackend)
    second = (
        GOOD.split("experiments:")[1]
        .replace("name: A", "name: B")
        .replace("type: pinv", "type: failing")
    )
    config = tmp_path / "two.yaml"
    config.write_text(GOOD + second.split("\n", 1)[1])
    status = main(["run", str(config), "--out", str(tmp_path / "out"), "--quiet", "--no-figures"])
    err = capsys.readouterr().err.strip()
    assert status == 2
    assert err == "otmm-qp: error: B/clik/OTMM: infeasible QP at step 5: joint box is empty"
    rows = list(csv.DictReader((tmp_path / "out" / "summary.csv").read_text().splitlines()))
    assert [(r["experiment"], r["completed"], r["steps"]) for r in rows] == [
        ("A", "True", "20"),
        ("B", "False", "5"),
    ]
    assert rows[1]["error_message"] == "infeasible QP at step 5: joint box is empty"


def test_run_writes_summary_and_series(tmp_path: Path) -> None:
    config = tmp_path / "good.yaml"
    config.write_text(GOOD)
    assert main(["run", str(config), "--out", str(tmp_path), "--quiet", "--no-figures"]) == 0
    rows = list(csv.DictReader((tmp_path / "summary.csv").read_text().splitlines()))
    assert [(r["experiment"], r["loop_mode"], r["controller"]) for r in rows] == [
        ("A", "clik", "OTMM")
    ]
    assert float(rows[0]["max_error"]) < 0.01
    series = list(csv.DictReader((tmp_path / "A" / "clik" / "OTMM.csv").read_text().splitlines()))
    assert len(series) == 20 and "sigma_min" in series[0]


def test_list_shows_every_group(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for word in [
        "robots:",
        "filters:",
        "p_functions:",
        "backends:",
        "trajectories:",
        "otmm",
        "cbrt",
        "dls_adaptive",
    ]:
        assert word in out


def test_console_script_exit_status() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "otmm_qp.cli", "run", "/nonexistent.yaml"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 2
    assert done.stderr.strip() == "otmm-qp: error: /nonexistent.yaml: no such config file"


def test_run_draws_per_run_and_comparison_figures(tmp_path: Path) -> None:
    config = tmp_path / "good.yaml"
    config.write_text(GOOD)
    assert main(["run", str(config), "--out", str(tmp_path), "--quiet"]) == 0
    for name in ["OTMM.png", "comparison.png"]:
        png = (tmp_path / "A" / "clik" / name).read_bytes()
        assert png.startswith(b"\x89PNG\r\n\x1a\n") and len(png) > 10_000
    html = (tmp_path / "report.html").read_text()
    assert "<html" in html and "data:image/png;base64," in html  # self-contained, figures in
    assert (
        main(
            ["run", str(config), "--out", str(tmp_path / "c"), "--quiet", "--figures", "comparison"]
        )
        == 0
    )
    assert sorted(p.name for p in (tmp_path / "c" / "A" / "clik").glob("*.png")) == [
        "comparison.png"
    ]


def test_default_run_is_the_paper_reproduction(tmp_path: Path) -> None:
    assert main(["run", "--out", str(tmp_path), "--quiet", "--figures", "none"]) == 0
    rows = list(csv.DictReader((tmp_path / "summary.csv").read_text().splitlines()))
    assert {r["experiment"] for r in rows} == {"E1", "E1_nearest", "E1_sigma_s", "E2", "E3"}
    assert {r["loop_mode"] for r in rows} == {"feedforward", "clik", "newton"}
    claims = (tmp_path / "claims.md").read_text()
    assert claims.count("| E2: RMRC breaks from the singular start |") == 3
    assert (tmp_path / "report.html").exists() and (tmp_path / "summary.md").exists()


@pytest.mark.parametrize("module", RETIRED_ALIASES)
def test_the_retired_python_m_aliases_are_gone(module: str) -> None:
    """The one-release ``python -m`` aliases are retired as promised: no ``main``, no
    ``__main__`` block (``otmm-qp study verdict|tradeoff|plants`` and ``otmm-qp pareto`` stay)."""
    imported = importlib.import_module(module)
    assert not hasattr(imported, "main")
    assert "__main__" not in Path(str(imported.__file__)).read_text(encoding="utf-8")
    assert not hasattr(importlib.import_module("otmm_qp.cli"), "deprecated_alias")
