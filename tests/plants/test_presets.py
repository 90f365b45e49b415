"""Plant presets and the bad input of issue 29: one line, exit 2, before any compute.

* each preset expands to its documented stages and declares what they declare;
* ``otmm-qp run`` refuses a negative or NaN margin, a deceleration of 0, an unknown preset
  and a preset on an arm without URDF efforts with one ``otmm-qp: error: FIELD: ...`` line,
  exit 2, and no output directory.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
import yaml

from otmm_qp.cli import main
from otmm_qp.exceptions import ConfigError
from otmm_qp.plants import DelayPlant, LagPlant, build_plant
from otmm_qp.plants.mujoco_plant import MujocoPlant
from otmm_qp.plants.presets import PRESETS
from otmm_qp.plants.rate_limit import RateLimitPlant
from tests.cli_errors import refusal_text


def test_presets_expand_to_their_documented_stages() -> None:
    franka = build_plant({"preset": "franka_fci"})
    rate, delay, body = franka.stages
    assert isinstance(rate, RateLimitPlant) and rate.acceleration == 7.5  # libfranka's joint 2
    assert isinstance(delay, DelayPlant) and delay.steps == 1
    assert isinstance(body, MujocoPlant) and body.frequency == 100.0 and body.timestep == 0.001
    assert body.command_cutoff == 100.0  # libfranka's low-pass, at the MuJoCo rate
    declared = franka.declares(0.02)
    assert declared.delay == 1 and declared.servo_frequency == 100.0
    assert declared.acceleration == (7.5,)
    # the body acts after every command stage wherever it is listed: its filter is not a lag
    # "before" a rate limiter listed after it
    build_plant(
        [{"type": "mujoco", "command_cutoff": 100.0}, {"type": "rate_limit", "acceleration": 5}]
    )
    for name, steps in (("ur_e_series", 1), ("ur_cb3", 2)):
        delay, lag, body = build_plant({"preset": name}).stages
        assert isinstance(delay, DelayPlant) and delay.steps == steps
        assert isinstance(lag, LagPlant) and lag.tau == 0.03
        assert isinstance(body, MujocoPlant)
        assert math.isclose(body.frequency * 2 * math.pi, 300.0)
    inside = build_plant([{"type": "sensor", "noise": 1e-4}, {"preset": "ur_cb3"}])
    assert [s.name for s in inside.stages] == ["sensor", "delay", "lag", "mujoco"]
    assert sorted(PRESETS) == ["fr3_fci", "franka_fci", "franka_fci_raw", "ur_cb3", "ur_e_series"]


def test_ur_lookahead_is_the_lag() -> None:
    """servoj's lookahead_time, a parameter of the UR presets, is the lag's τ."""
    for name in ("ur_e_series", "ur_cb3"):
        _, lag, _ = build_plant({"preset": name, "lookahead": 0.1}).stages
        assert isinstance(lag, LagPlant) and lag.tau == 0.1
        _, lag, _ = build_plant({"preset": name}).stages
        assert isinstance(lag, LagPlant) and lag.tau == 0.03


@pytest.mark.parametrize(
    ("name", "acceleration", "jerk"), [("franka_fci_raw", 7.5, 3750.0), ("fr3_fci", 10.0, 5000.0)]
)
def test_raw_franka_presets_check_the_stream_without_a_rate_limiter(
    name: str, acceleration: float, jerk: float
) -> None:
    """libfranka's default (limit_rate off): no rate limiter, the FCI's thresholds declared."""
    plant = build_plant({"preset": name})
    assert [stage.name for stage in plant.stages] == ["interface", "delay", "mujoco"]
    declared = plant.declares(0.001)
    assert declared.acceleration == ()  # nothing smooths the stream
    assert declared.interface_acceleration == (acceleration,)
    assert declared.interface_jerk == (jerk,)
    assert declared.interface_period == 0.001  # the FCI's 1 kHz
    assert declared.delay == 1 and declared.servo_frequency == 100.0


@pytest.mark.parametrize(
    ("spec", "field"),
    [
        ({"preset": "kuka_lbr"}, "plant.preset"),
        ({"preset": "ur_cb3", "seed": 1}, "plant"),
        ({"preset": "franka_fci", "lookahead": 0.1}, "plant"),
        ({"preset": "ur_e_series", "lookahead": 0.01}, "plant.lookahead"),
        ({"preset": "ur_e_series", "lookahead": float("nan")}, "plant.lookahead"),
        ([{"preset": 7}], "plant.0.preset"),
    ],
)
def test_bad_presets_name_the_field(spec: Any, field: str) -> None:
    with pytest.raises(ConfigError) as error:
        build_plant(spec)
    assert error.value.field == field and "\n" not in str(error.value)


PLANAR: dict[str, Any] = {
    "name": "bad-input",
    "dt": 0.02,
    "experiments": [
        {
            "name": "e",
            "robot": {"type": "planar", "link_lengths": [1.0, 0.8], "limits": [[-2, 2]] * 2},
            "q0": [0.3, 0.4],
            "trajectory": {"type": "circle", "centre": [1.0, 0.5], "radius": 0.2, "period": 2.0},
            "duration": 0.2,
            "controllers": [{"name": "qp", "backend": {"type": "qp"}}],
        }
    ],
}


def _run(tmp_path: Path, capsys: pytest.CaptureFixture[str], **edits: Any) -> tuple[int, str]:
    config = yaml.safe_load(yaml.safe_dump(PLANAR))
    experiment = config["experiments"][0]
    if "limits" in edits:
        experiment["controllers"][0]["backend"]["limits"] = edits["limits"]
    if "plant" in edits:
        experiment["plant"] = edits["plant"]
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump(config), encoding="utf-8")
    out = tmp_path / "out"
    code = main(["run", str(path), "--out", str(out)])
    err = capsys.readouterr().err
    assert not out.exists()  # refused before any compute
    return code, err


@pytest.mark.parametrize(
    ("edits", "expected"),
    [
        ({"limits": [{"type": "predicted_position", "margin": -0.01}]}, "limits.0.margin"),
        ({"limits": [{"type": "predicted_position", "margin": float("nan")}]}, "limits.0.margin"),
        ({"limits": [{"type": "predicted_position", "deceleration": 0.0}]}, "deceleration"),
        ({"plant": {"preset": "kuka_lbr"}}, "plant.preset: unknown preset 'kuka_lbr'"),
        ({"plant": {"preset": "franka_fci"}}, "needs a positive URDF effort"),
        ({"plant": {"type": "rate_limit", "acceleration": 0.0}}, "plant.acceleration"),
        ({"plant": {"type": "rate_limit", "acceleration": -1.0}}, "plant.acceleration"),
        ({"plant": {"type": "rate_limit", "acceleration": float("nan")}}, "plant.acceleration"),
        ({"plant": {"type": "rate_limit"}}, "acceleration"),
        ({"plant": {"type": "rate_limit", "acceleration": [1.0, 2.0, 3.0]}}, "acceleration"),
        (
            {"plant": [{"type": "lag", "tau": 0.01}, {"type": "rate_limit", "acceleration": 5}]},
            "list the rate limiter before every lag",
        ),
        ({"limits": [{"type": "predicted_position", "rate_limit": 0.0}]}, "rate_limit"),
        ({"limits": [{"type": "command", "acceleration": -1.0}]}, "limits.0.acceleration"),
        ({"limits": [{"type": "command", "acceleration": float("nan")}]}, "acceleration"),
        ({"limits": [{"type": "command", "acceleration": 5, "jerk": float("nan")}]}, "jerk"),
        ({"limits": [{"type": "command", "acceleration": [1.0, 2.0, 3.0]}]}, "acceleration"),
        ({"limits": [{"type": "command", "jerk": 100.0}]}, "jerk: needs an acceleration limit"),
        ({"plant": {"type": "interface", "jerk": 5000.0}}, "acceleration"),
        ({"plant": {"type": "interface", "acceleration": 10, "jerk": -1}}, "plant.jerk"),
        ({"plant": {"type": "interface", "acceleration": [1.0, 2.0, 3.0]}}, "acceleration"),
        ({"plant": {"preset": "fr3"}}, "plant.preset: unknown preset 'fr3'"),
    ],
)
def test_bad_input_is_one_line_exit_2_before_compute(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], edits: dict[str, Any], expected: str
) -> None:
    code, err = _run(tmp_path, capsys, **edits)
    assert code == 2
    assert expected in refusal_text(err)  # first line <= 200 characters, details after
