"""Figures: plot_run / plot_comparison / figure_hook write valid PNGs, also for odd runs."""

from __future__ import annotations

import dataclasses
import struct
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from otmm_qp import registry
from otmm_qp.controller import Controller
from otmm_qp.filters.otmm import OtmmFilter
from otmm_qp.output.figures import DPI, figure_hook, plot_comparison, plot_run
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.runner.run import RunRecord
from otmm_qp.simulation import Episode, Loop, simulate
from otmm_qp.simulation.run_result import RunResult
from otmm_qp.trajectories.circle import CircleTrajectory

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def png_size(path: Path) -> tuple[int, int]:
    """Width and height [px] from the IHDR chunk, after checking the signature."""
    data = path.read_bytes()
    assert len(data) > 5_000, f"{path} is suspiciously small ({len(data)} bytes)"
    assert data[:8] == PNG_SIGNATURE
    assert data[12:16] == b"IHDR"
    width, height = struct.unpack(">II", data[16:24])
    return int(width), int(height)


def run(controller: Controller, duration: float = 1.2) -> RunResult:
    """The paper's E1 circle sped up 5×: passes the stretched singularity at t = 1 s."""
    robot = PlanarArm([1.0, 0.8])
    q0 = np.array([0.927, -2.5])
    trajectory = CircleTrajectory(
        start=robot.forward(q0),
        centre=[1.2, 0.0],
        radius=0.6,
        period=2.0,
        direction="clockwise",
        start_angle=np.pi,
    )
    return simulate(
        Episode(robot, trajectory, q0, 0.02, duration, Loop("clik", 10.0), name="T"), controller
    )


def pinv() -> Any:
    return registry.load(registry.BACKENDS, "pinv")()


@pytest.fixture(scope="module")
def runs() -> list[RunResult]:
    otmm = run(Controller("OTMM-cbrt", [OtmmFilter(0.05, "cbrt")], pinv()))
    rmrc = run(Controller("RMRC", [], pinv()))
    # A blow-up: one step at 1e4 rad/s with odd backend statuses (must not flatten the rest).
    spike = dataclasses.replace(rmrc, controller="RMRC spike", qdot=rmrc.qdot.copy())
    spike.qdot[10] = [1.0e4, -3.0e3]
    spike.status = rmrc.status.copy()
    spike.status[10] = "nonfinite"
    spike.status[11:14] = "bounded"
    spike.status[20] = "weird"
    # Stopped early after 3 steps.
    short = dataclasses.replace(
        otmm,
        controller="OTMM stopped",
        **{
            name: getattr(otmm, name)[:3]
            for name in (
                "t",
                "q",
                "qdot",
                "position",
                "position_desired",
                "error",
                "sigma_min",
                "p",
                "filter_active",
                "removed",
                "damping",
                "scale",
                "weak_speed",
                "status",
                "step_time",
            )
        },
        error_message="step 3: infeasible QP (test)",
    )
    return [otmm, rmrc, spike, short]


def test_runs_look_as_intended(runs: list[RunResult]) -> None:
    otmm, rmrc, spike, short = runs
    assert otmm.steps == 60 and short.steps == 3
    assert np.any(otmm.filter_active), "the OTMM run should reach σ_min ≤ σ_S"
    assert np.abs(spike.qdot).max() / np.abs(otmm.qdot).max() > 20


@pytest.mark.parametrize("index", [0, 2, 3], ids=["otmm", "spike", "stopped"])
def test_plot_run_writes_png(runs: list[RunResult], index: int, tmp_path: Path) -> None:
    path = tmp_path / "sub" / "run.png"
    plot_run(runs[index], path, sigma_s=0.05)
    width, height = png_size(path)
    assert 0.9 * 13.0 * DPI <= width <= 1.1 * 13.0 * DPI
    assert 5.0 * DPI <= height <= 8.0 * DPI


def test_plot_run_3d_pose(runs: list[RunResult], tmp_path: Path) -> None:
    base = runs[0]
    n = base.steps
    lift = np.column_stack([base.position, np.linspace(0.0, 0.01, n)])
    lift_desired = np.column_stack([base.position_desired, np.zeros(n)])
    error = np.column_stack([base.error, np.zeros(n), np.linspace(1e-6, 1e-2, (n)), base.error])
    pose = dataclasses.replace(
        base, task_kind="pose", position=lift, position_desired=lift_desired, error=error
    )
    path = tmp_path / "pose.png"
    plot_run(pose, path)
    png_size(path)


def test_plot_comparison_writes_png(runs: list[RunResult], tmp_path: Path) -> None:
    path = tmp_path / "comparison.png"
    plot_comparison(runs, path, "T · clik", 0.05)
    width, height = png_size(path)
    assert width >= 4 * 2.0 * DPI  # one column per controller
    assert 6.0 * DPI <= height <= 9.0 * DPI
    single = tmp_path / "single.png"
    plot_comparison(runs[:1], single, "T · clik", None)
    png_size(single)


def test_plot_comparison_with_a_run_that_never_moves(runs: list[RunResult], tmp_path: Path) -> None:
    """A run whose q̇ is 0 throughout (a backend stuck at a singular start) beside runs that
    move: the speed axis is symlog from the moving runs' peaks, the note's ratio as well (it
    once divided by the 0 peak: ZeroDivisionError on configs/strategies/paper.yaml)."""
    still = dataclasses.replace(runs[0], controller="stuck", qdot=np.zeros_like(runs[0].qdot))
    spike = next(r for r in runs if r.controller == "RMRC spike")
    path = tmp_path / "comparison.png"
    plot_comparison([still, runs[0], spike], path, "T · clik", 0.05)
    png_size(path)


def test_figure_hook_layout(runs: list[RunResult], tmp_path: Path) -> None:
    prepared: Any = SimpleNamespace(config=SimpleNamespace(name="T"), loop_modes=["clik"])
    records = [RunRecord(r, None) for r in (runs[1], runs[2])]  # type: ignore[arg-type]
    hook = figure_hook(0.05, workers=2)
    hook(prepared, records, None)  # no output folder: nothing happens
    hook(prepared, records, tmp_path)
    folder = tmp_path / "T" / "clik"
    names = sorted(p.name for p in folder.iterdir())
    assert names == ["RMRC.png", "RMRC_spike.png", "comparison.png"]
    for path in folder.iterdir():
        png_size(path)


def test_figure_hook_without_per_run(runs: list[RunResult], tmp_path: Path) -> None:
    prepared: Any = SimpleNamespace(config=SimpleNamespace(name="T"), loop_modes=["clik"])
    records = [RunRecord(r, None) for r in runs[:2]]  # type: ignore[arg-type]  # serial path
    figure_hook(0.05, per_run=False, workers=1)(prepared, records, tmp_path)
    assert [p.name for p in (tmp_path / "T" / "clik").iterdir()] == ["comparison.png"]
