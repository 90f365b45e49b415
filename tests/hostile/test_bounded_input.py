"""Every size-like parameter has a declared bound, refused in one line before any compute."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from otmm_qp import registry
from otmm_qp.cli import main
from otmm_qp.exceptions import ParameterError, one_line
from tests.cli_errors import refusal_text

RUN = """\
version: 2
experiments:
  - name: e
    robot: {type: planar, link_lengths: [1.0, 0.8]}
    q0: [0.927, -2.5]
    trajectory: {type: circle, centre: [1.2, 0.0], radius: 0.6, period: 10.0}
    plant: PLANT
    controllers:
      - {name: pinv, backend: {type: pinv}, conditioning: CONDITIONING}
"""

CASES = {
    "delay steps": (
        "{type: delay, steps: 1000000000}",
        "[]",
        r"plant\.steps: must be an integer in \[0, 100000\] \[periods; .* MiB .*got 1000000000$",
    ),
    "sensor counts beyond float": (
        "{type: sensor, counts: 1" + "0" * 400 + "}",
        "[]",
        r"plant\.counts: must be an integer in \(0, 4\.29497e\+09\] \[counts/rev\] or None, got",
    ),
    "mujoco timestep": (
        "{type: mujoco, timestep: 1.0e-9}",
        "[]",
        r"plant\.timestep: must be a finite number >= 1e-06 \[s\], got 1e-09$",
    ),
    "jerk Ruckig refuses": (
        "{type: ideal}",
        "[{type: jerk_limit, acceleration: 10, jerk: 1.0e-300}]",
        r"conditioning\.0\.jerk: must be in \[1e-06, 1e\+12\] \[rad/s³\]",
    ),
    "acceleration Ruckig refuses": (
        "{type: ideal}",
        "[{type: jerk_limit, acceleration: 1.0e-15, jerk: 10}]",
        r"conditioning\.0\.acceleration: must be in \[1e-06, 1e\+12\]",
    ),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_size_like_parameters_are_bounded(
    case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plant, conditioning, pattern = CASES[case]
    config = tmp_path / "run.yaml"
    config.write_text(RUN.replace("PLANT", plant).replace("CONDITIONING", conditioning))
    status = main(["run", str(config), "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert status == 2, err
    text = refusal_text(err)  # a first line of at most 200 characters, details after
    assert re.search(pattern, text), text
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").rglob("*.csv"))


def test_mujoco_substeps_per_period_are_capped() -> None:
    """A timestep far below dt would make each control period thousands of MuJoCo steps."""
    pytest.importorskip("mujoco")
    from otmm_qp.plants.mujoco_plant import MAX_SUBSTEPS
    from otmm_qp.robots.planar_arm import PlanarArm

    plant = registry.create(registry.PLANTS, "mujoco", {"timestep": 1e-6}, "plant")
    robot = PlanarArm([1.0, 0.8])
    with pytest.raises(ParameterError, match=rf"timestep: dt / timestep = \d+ .* {MAX_SUBSTEPS}"):
        plant.reset(robot, np.array([0.9, -2.5]), 0.02)


def test_error_lines_cut_long_values(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["list", "--params", "x" * 10_000]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and len(err) < 200, len(err)
    assert one_line("a\nb " + "y" * 500 + "z:") == "a b " + "y" * 28 + "..." + "y" * 27 + "z:"


def test_mujoco_substeps_count_against_max_steps(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """500 control steps × 200 MuJoCo steps each are 100,000 plant steps, not 500."""
    pytest.importorskip("mujoco")
    config = tmp_path / "run.yaml"
    plant = "{type: mujoco, timestep: 1.0e-4, effort_limit: 50.0}"
    text = RUN.replace("PLANT", plant).replace("CONDITIONING", "[]")
    config.write_text(text.replace("version: 2\n", "version: 2\nmax_steps: 2000\n"))
    assert main(["run", str(config), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    err = refusal_text(err)
    assert (
        "plant: 500 control steps × 200 plant steps per period = 1e+05 exceeds max_steps = 2000"
        in err
    )


STUDY = """\
version: 2
name: bounded
dt: 0.02
max_steps: 2000
reference: {enabled: false}
robots:
  - name: planar2
    robot: {type: planar, link_lengths: [1.0, 0.8]}
generators:
  - {type: near_singular, count: 1, duration: [1.0, 1.0]}
PLANTS
controllers:
  - name: pinv
    backend: {type: pinv}
    CONTROLLER_PLANT
"""

MUJOCO = "{type: mujoco, timestep: 1.0e-4, effort_limit: 50.0}"


@pytest.mark.parametrize(
    ("plants", "controller_plant", "pattern"),
    [
        (  # the plants axis: 75 control steps × 200 MuJoCo steps each
            "plants:\n  - {name: ideal, plant: {type: ideal}}\n"
            f"  - {{name: mj, plant: {MUJOCO}}}",
            "",
            r"plants\.1\.plant: \d+ control steps × 200 plant steps per period = [\d.e+]+ "
            r"exceeds max_steps = 2000",
        ),
        (  # a controller's own plant
            "",
            f"plant: {MUJOCO}",
            r"controllers\.0 \(pinv\)\.plant: \d+ control steps × 200 plant steps per period",
        ),
        (  # a delay's ring buffer is bounded where it is declared
            "plants:\n  - {name: slow, plant: {type: delay, steps: 1000000000}}",
            "",
            r"plants\.0\.plant\.steps: must be an integer in \[0, 100000\] \[periods; .* MiB",
        ),
    ],
    ids=["plants-axis-substeps", "controller-plant-substeps", "plants-axis-delay"],
)
def test_study_plants_are_bounded_like_a_run(
    plants: str,
    controller_plant: str,
    pattern: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """A study refuses a plant a run file refuses, in one line, before any episode runs."""
    if "mujoco" in plants + controller_plant:
        pytest.importorskip("mujoco")
    config = tmp_path / "study.yaml"
    text = STUDY.replace("PLANTS", plants).replace("CONTROLLER_PLANT", controller_plant)
    config.write_text(text, encoding="utf-8")
    out = tmp_path / "out"
    status = main(["study", str(config), "--out", str(out), "--workers", "1", "--quiet"])
    err = capsys.readouterr().err
    assert status == 2, err
    text = refusal_text(err)
    assert re.search(pattern, text), text
    assert not out.exists() or not any(out.rglob("*.parquet"))
