"""Every CLI subcommand, benchmark script and example runs at a tiny size and says what it did."""

from __future__ import annotations

import json
import runpy
from pathlib import Path

import numpy as np
import pytest

from otmm_qp.cli import main
from otmm_qp.exceptions import DimensionError, ParameterError, PluginNotFound
from tests.factories import run_script

ROOT = Path(__file__).parents[2]
TINY_CONFIG = """
name: tiny
loop_modes: [clik]
experiments:
  - name: planar
    robot: {type: planar, link_lengths: [1.0, 1.0]}
    q0: [0.3, 1.2]
    trajectory: {type: circle, centre: [1.2, 0.5], radius: 0.3, period: 1.0}
    duration: 0.2
    controllers:
      - {name: pinv, backend: {type: pinv}}
      - {name: otmm+qp, filters: [{type: otmm, sigma_s: 0.05}], backend: {type: qp}}
"""


def test_run_then_report(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = tmp_path / "tiny.yaml"
    config.write_text(TINY_CONFIG)
    out = tmp_path / "out"
    assert main(["run", str(config), "--out", str(out), "--figures", "none", "--quiet"]) == 0
    assert "2 runs in" in capsys.readouterr().out
    rows = (out / "summary.csv").read_text().splitlines()
    assert len(rows) == 3 and rows[0].startswith("experiment")
    (out / "report.html").unlink()
    assert main(["report", str(out)]) == 0
    assert "report:" in capsys.readouterr().out and (out / "report.html").is_file()


def test_list_names_every_group(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["list"]) == 0
    text = capsys.readouterr().out
    for heading in ("robots:", "filters:", "p_functions:", "backends:", "trajectories:"):
        assert heading in text
    assert "  qp " in text and "  otmm " in text


def _check_bench_output(out: Path, scenarios: int) -> dict[str, object]:
    result = json.loads((out / "bench.json").read_text())
    assert len(result["scenarios"]) == scenarios
    for scenario in result["scenarios"]:
        rows = {row["pipeline"]: row for row in scenario["rows"]}
        assert "otmm+qp (daqp, persistent, QP every step)" in rows
        assert all(row["median_us"] > 0 for row in rows.values())
        floor = rows["floor (FK + Jacobian + dgesdd)"]  # timed in the same blocks
        assert floor["ratio_to_floor"] == 1.0 and floor["library"] == "floor"
        for row in rows.values():
            assert row["ratio_to_floor"] == pytest.approx(row["median_us"] / floor["median_us"])
        if "pink (daqp)" in rows:
            assert rows["pink (daqp)"]["ratio_to_pink_daqp"] == pytest.approx(1.0)
    assert "| × pink (daqp) | × floor |" in (out / "bench.md").read_text()
    return result


def test_bench_subcommand(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "bench"
    assert main(["bench", "--out", str(out), "--steps", "10"]) == 0
    assert "### Panda, 6-D pose task (7 DoF)" in capsys.readouterr().out
    _check_bench_output(out, 2)


def test_bench_rejects_too_few_steps(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["bench", "--out", str(tmp_path), "--steps", "3"]) == 2
    assert "--steps: must be in [10, 100000], got 3" in capsys.readouterr().err


def test_bench_cli_accepts_the_command_it_records(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--rounds and --planar-only: bench.json records a command the CLI runs as given."""
    out = tmp_path / "bench"
    args = ["bench", "--out", str(out), "--steps", "10", "--rounds", "2", "--planar-only"]
    assert main(args) == 0
    result = _check_bench_output(out, 1)
    assert result["rounds"] == 2
    assert result["command"] == "otmm-qp " + " ".join(args)
    assert main(["bench", "--out", str(out), "--steps", "10", "--rounds", "0"]) == 2
    assert "--rounds: must be in [1, 1000], got 0" in capsys.readouterr().err


def test_bench_step_script(tmp_path: Path) -> None:
    script = runpy.run_path(str(ROOT / "benchmarks" / "bench_step.py"))
    out = tmp_path / "bench"
    argv = ["--out", str(out), "--steps", "10", "--rounds", "1", "--planar-only"]
    assert script["main"](argv) == 0
    _check_bench_output(out, 1)


def test_bench_arm_step_script(capsys: pytest.CaptureFixture[str]) -> None:
    script = runpy.run_path(str(ROOT / "benchmarks" / "bench_arm_step.py"))
    results = script["main"](["--steps", "20"])
    assert "KinematicState.compute" in results
    assert "otmm+qp (daqp, persistent, QP every step) [limits active]" in results
    assert all(median > 0 for median, _ in results.values())
    assert "median" in capsys.readouterr().out


def test_bench_strategies_runs_tiny() -> None:
    done = run_script(
        "benchmarks/bench_strategies.py", "--steps", "20", "--rounds", "1", timeout=120
    )
    assert done.returncode == 0, done.stderr
    rows = {line.split()[0] for line in done.stdout.splitlines() if line.strip()}
    assert {"otmm+pinv", "otmm-directional+pinv", "jparse", "sns", "manipulability"} <= rows


def test_bench_instructions_runs_tiny() -> None:
    """The phases of the instruction count run (without valgrind: counting takes minutes)."""
    script = "benchmarks/bench_instructions.py"
    done = run_script(script, "--steps", "10", "--passes", "1", "--no-valgrind", timeout=120)
    assert done.returncode == 0, done.stderr
    assert "ran 7 phases x 1 passes x 10 states" in done.stdout
    refused = run_script(script, "--steps", "3")
    assert refused.returncode == 2 and "--steps must be >= 10" in refused.stderr


def test_bench_reach_runs_one_arm() -> None:
    done = run_script("benchmarks/bench_reach.py", "ur5")
    assert done.returncode == 0, done.stderr
    row = done.stdout.strip().splitlines()[-1].split("|")
    outer, found, offsets = float(row[2]), float(row[3]), float(row[8])
    assert row[1].strip() == "ur5" and found <= outer <= offsets  # a bracket under the old bound


def test_bench_decide_runs_tiny(tmp_path: Path) -> None:
    out = tmp_path / "decide.json"
    done = run_script("benchmarks/bench_decide.py", "--studies", "20", "--json", str(out))
    assert done.returncode == 0, done.stderr
    assert out.is_file() and "|" in done.stdout


def test_stress_signals_runs_once() -> None:
    """One interrupted study and its resume: the stress script's checks pass (exit 0)."""
    done = run_script("benchmarks/stress_signals.py", "--runs", "1", "--seed", "1", timeout=600)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "baseline --workers 1" in done.stdout


def test_every_benchmark_script_and_example_is_tested() -> None:
    # bench_qp_session: test_qp_bench.py; bench_study: test_studies_shipped.py;
    # bench_reference: test_studies_oracle.py.
    scripts = {p.name for p in (ROOT / "benchmarks").glob("*.py")}
    assert scripts <= {
        "bench_step.py",
        "bench_arm_step.py",
        "bench_qp_session.py",
        "bench_strategies.py",
        "bench_study.py",
        "bench_reference.py",
        "bench_plant.py",  # test_plant_runs.py
        "bench_instructions.py",
        "bench_preview_cpu.py",  # test_qp_bench.py
        "profile_preview.py",  # test_qp_bench.py
        "bench_reach.py",
        "bench_decide.py",
        "bench_coupled_planar.py",  # reference/test_certificates.py
        "profile_reference.py",  # reference/test_profile_script.py
        "stress_signals.py",
    }
    examples = {p.name for p in (ROOT / "examples").iterdir()}
    assert examples == {"otmm_before_qp.py", "otmm_qp_example_plugin"}  # test_examples.py


# ----------------------------------------------------------- the Python API
def test_api_shapes_raise_dimension_error() -> None:
    from otmm_qp.controller import Controller
    from otmm_qp.robots.planar_arm import PlanarArm
    from otmm_qp.state import KinematicState
    from otmm_qp_controllers.pinv import PseudoInverseBackend

    robot = PlanarArm([1.0, 1.0])
    with pytest.raises(DimensionError, match=r"q: expected shape \(2,\), got \(2, 2\)"):
        KinematicState.compute(robot, np.zeros((2, 2)))
    with pytest.raises(DimensionError, match="weight"):
        KinematicState.compute(robot, np.array([0.3, 1.0]), np.ones(3))
    state = KinematicState.compute(robot, np.array([0.3, 1.0]))
    controller = Controller("pinv", [], PseudoInverseBackend())
    controller.bind(robot, 0.01)
    with pytest.raises(DimensionError, match="xdot"):
        controller.step(state, np.zeros(3), np.zeros(2))
    with pytest.raises(DimensionError, match=r"qdot_prev: expected shape \(2,\), got \(5,\)"):
        controller.step(state, np.zeros(2), np.zeros(5))


@pytest.mark.parametrize(
    ("argument", "value"),
    [("dt", 0.0), ("dt", -0.01), ("dt", float("nan")), ("dt", float("inf")),
     ("duration", -1.0), ("duration", float("nan")), ("duration", float("inf")),
     ("max_steps", 0), ("max_steps", 2.5)],
)  # fmt: skip
def test_episode_rejects_bad_time_arguments(argument: str, value: float) -> None:
    from otmm_qp.robots.planar_arm import PlanarArm
    from otmm_qp.simulation import Episode
    from otmm_qp.trajectories.circle import CircleTrajectory

    robot = PlanarArm([1.0, 1.0])
    q0 = np.array([0.3, 1.2])
    trajectory = CircleTrajectory(robot.forward(q0), [1.2, 0.5], 0.3, 1.0)
    arguments = {"dt": 0.01, "duration": 0.1, argument: value}
    with pytest.raises(ParameterError, match=f"^{argument}: "):
        Episode(robot, trajectory, q0, **arguments)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("mode", "gain", "field"),
    [("open", 10.0, "loop_mode"), ("clik", -1.0, "clik_gain"), ("clik", float("inf"), "clik_gain"),
     ("clik", float("nan"), "clik_gain")],
)  # fmt: skip
def test_loop_rejects_bad_mode_and_gain(mode: str, gain: float, field: str) -> None:
    from otmm_qp.simulation import Loop

    with pytest.raises(ParameterError, match=f"^{field}: "):
        Loop(mode, gain)  # type: ignore[arg-type]


def test_episode_is_frozen_and_its_arrays_read_only() -> None:
    import dataclasses

    from otmm_qp.robots.planar_arm import PlanarArm
    from otmm_qp.simulation import Episode
    from otmm_qp.trajectories.circle import CircleTrajectory

    robot = PlanarArm([1.0, 1.0])
    q0 = np.array([0.3, 1.2])
    weight = [1.0, 2.0]
    episode = Episode(robot, CircleTrajectory(robot.forward(q0), [1.2, 0.5], 0.3, 1.0), q0, 0.01,
                      0.1, task_weight=weight)  # fmt: skip
    q0[0] = 9.0  # the episode kept its own copy
    assert episode.q0[0] == 0.3 and episode.steps == 10
    with pytest.raises(dataclasses.FrozenInstanceError):
        episode.dt = 0.5  # type: ignore[misc]
    with pytest.raises(ValueError, match="read-only"):
        episode.q0[0] = 1.0
    assert episode.task_weight is not None and episode.task_weight.tolist() == weight
    with pytest.raises(DimensionError, match="task_weight"):
        Episode(episode.robot, episode.trajectory, q0, 0.01, 0.1, task_weight=[1.0])
    with pytest.raises(ParameterError, match="task_weight"):
        Episode(episode.robot, episode.trajectory, q0, 0.01, 0.1, task_weight=[1.0, float("inf")])
    with pytest.raises(ParameterError, match=r"max_steps = 5 .*GiB"):
        Episode(episode.robot, episode.trajectory, q0, 0.01, 0.1, max_steps=5)


def test_simulate_with_nan_q0_returns_zero_steps_and_says_why() -> None:
    from otmm_qp.controller import Controller
    from otmm_qp.robots.planar_arm import PlanarArm
    from otmm_qp.simulation import Episode, simulate
    from otmm_qp.trajectories.circle import CircleTrajectory
    from otmm_qp_controllers.pinv import PseudoInverseBackend

    robot = PlanarArm([1.0, 1.0])
    trajectory = CircleTrajectory(np.array([1.0, 1.0]), [1.2, 0.5], 0.3, 1.0)
    controller = Controller("p", [], PseudoInverseBackend())
    episode = Episode(robot, trajectory, np.array([np.nan, 1.0]), 0.01, 0.1)
    result = simulate(episode, controller)
    assert result.steps == 0 and result.error_message is not None
    assert "q0" in result.error_message
    with pytest.raises(DimensionError, match="q0"):
        Episode(robot, trajectory, np.zeros(3), 0.01, 0.1)


def test_unknown_plugin_message_singularises_trajectories() -> None:
    assert "unknown trajectory 'x'" in str(PluginNotFound("otmm_qp.trajectories", "x", []))
    assert "unknown backend 'x'" in str(PluginNotFound("otmm_qp.backends", "x", []))
