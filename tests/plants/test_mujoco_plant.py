"""The MuJoCo plant: tracks the ideal plant with stiff servos, keeps torques within limits, and
refuses models it cannot simulate with one line naming the joint or link."""

from __future__ import annotations

import dataclasses
import sys
from functools import cache

import numpy as np
import pytest

pytest.importorskip("mujoco")

from otmm_qp.config.load import load_config  # noqa: E402
from otmm_qp.exceptions import ConfigError  # noqa: E402
from otmm_qp.metrics import compute_metrics  # noqa: E402
from otmm_qp.plants import build_plant  # noqa: E402
from otmm_qp.runner.plant_stage import check_plant  # noqa: E402
from otmm_qp.runner.prepare import PreparedExperiment, prepare_experiment  # noqa: E402
from otmm_qp.simulation.run_result import RunResult  # noqa: E402
from otmm_qp.simulation.simulate import simulate  # noqa: E402

#: Tolerance of the stiff, gravity-free MuJoCo plant against the ideal one on panda_reach.
JOINT_TOLERANCE = 1e-3  # [rad]
POSITION_TOLERANCE = 1e-4  # [m]


@cache
def panda() -> PreparedExperiment:
    return prepare_experiment(load_config("configs/arms/panda_reach.yaml"), 0)


def run(spec: object, controller: str = "dls", duration: float | None = None) -> RunResult:
    prep = panda()
    chosen = next(c for c in prep.controllers if c.name == controller)
    episode = prep.episodes[0]
    if duration is not None:
        episode = dataclasses.replace(episode, duration=duration)
    return simulate(episode, chosen, plant=build_plant(spec))


def test_stiff_servos_without_gravity_track_the_ideal_plant() -> None:
    ideal = run(None)
    gaps = []
    for frequency, timestep in ((5.0, 0.002), (30.0, 0.001)):
        spec = {"type": "mujoco", "gravity": False, "frequency": frequency, "timestep": timestep}
        result = run(spec)
        assert result.error_message is None and result.steps == ideal.steps
        gaps.append(float(np.max(np.abs(result.q - ideal.q))))
    stiff = result
    assert gaps[1] < gaps[0]  # stiffer servos track closer
    assert gaps[1] < JOINT_TOLERANCE
    gap = np.linalg.norm(stiff.position - ideal.position, axis=1)
    assert float(np.max(gap)) < POSITION_TOLERANCE
    metrics = compute_metrics(stiff)
    assert 0.0 < float(metrics["peak_torque_ratio"]) <= 1.0
    assert float(metrics["speed_gap_max"]) > 0.0


def test_gravity_is_compensated_through_the_actuators() -> None:
    free = run({"type": "mujoco", "gravity": False}, duration=1.0)
    compensated = run({"type": "mujoco"}, duration=1.0)
    sagging = run({"type": "mujoco", "compensation": "none"}, duration=1.0)
    assert np.max(np.abs(compensated.q - free.q)) < 1e-6
    assert np.max(np.abs(sagging.q - free.q)) > 1e-3  # gravity without compensation: it sags
    assert np.nanmax(compensated.torque_ratio) > np.nanmax(free.torque_ratio)


def test_reported_torques_never_exceed_the_limits_and_saturation_is_counted() -> None:
    prep = panda()
    plant = build_plant({"type": "mujoco", "frequency": 40.0, "timestep": 0.001})
    plant.reset(prep.robot, prep.q0, prep.dt)
    body = plant.body
    q = prep.q0
    rng = np.random.default_rng(5)
    ratios, saturated = [], 0
    for _ in range(60):  # bang-bang joint speed commands at the speed limits
        command = prep.robot.velocity_limits * rng.choice([-1.0, 1.0], prep.robot.nv)
        step = plant.advance(q, command)
        assert step.stable
        applied = np.abs(body._data.qfrc_actuator[body._qvel_index])  # noqa: SLF001
        assert np.all(applied <= body.tau_max * (1 + 1e-12))
        ratios.append(step.torque_ratio)
        saturated += step.saturated
        q = step.q
    assert max(ratios) <= 1.0 + 1e-12
    assert saturated > 0 and max(ratios) == pytest.approx(1.0)


def test_an_unstable_simulation_is_a_stored_status() -> None:
    result = run({"type": "mujoco", "unstable_speed": 1e-3}, duration=1.0)
    assert result.error_message is not None and "unstable" in result.error_message
    assert result.steps >= 1
    metrics = compute_metrics(result)
    assert metrics["completed"] is False


def _with_urdf(robot: object, edit: object) -> object:
    description = robot.peer_description()  # type: ignore[attr-defined]
    changed = dataclasses.replace(description, urdf=edit(description.urdf))  # type: ignore[operator]

    class Edited(type(robot)):  # type: ignore[misc]
        def peer_description(self) -> object:
            return changed

    clone = object.__new__(Edited)
    clone.__dict__.update(robot.__dict__)  # type: ignore[attr-defined]
    return clone


def test_missing_effort_limit_names_the_joint_and_the_override() -> None:
    prep = panda()
    robot = _with_urdf(prep.robot, lambda u: u.replace('effort="12.0"', 'effort="0"', 1))
    with pytest.raises(ConfigError) as info:
        check_plant({"type": "mujoco"}, robot, prep.q0, prep.dt, "experiments.0.plant")
    message = str(info.value)
    assert message.startswith("experiments.0.plant.effort_limit: joint 'panda_joint5'")
    assert "no default is used" in message
    check_plant({"type": "mujoco", "effort_limit": 10.0}, robot, prep.q0, prep.dt, "p")


def test_missing_inertia_names_the_link() -> None:
    prep = panda()

    def drop(urdf: str) -> str:
        start = urdf.index('<link name="panda_link3"')
        inertial = urdf.index("<inertial>", start)
        return urdf[:inertial] + urdf[urdf.index("</inertial>", inertial) + 11 :]

    robot = _with_urdf(prep.robot, drop)
    with pytest.raises(ConfigError, match="link 'panda_link3' .*no <inertial>"):
        check_plant({"type": "mujoco"}, robot, prep.q0, prep.dt, "experiments.0.plant")


def test_a_model_mujoco_cannot_compile_is_one_line() -> None:
    prep = panda()

    def bad_inertia(urdf: str) -> str:
        start = urdf.index("ixx=", urdf.index('<link name="panda_link3"'))
        return urdf[:start] + 'ixx="-1" ' + urdf[urdf.index(" ", start) + 1 :]

    robot = _with_urdf(prep.robot, bad_inertia)
    with pytest.raises(ConfigError) as info:
        check_plant({"type": "mujoco", "effort_limit": 5.0}, robot, prep.q0, prep.dt, "f.plant")
    assert str(info.value).startswith("f.plant") and "\n" not in str(info.value)


def test_mujoco_not_installed(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "mujoco", None)
    with pytest.raises(ConfigError, match=r"^plant.type: MuJoCo is not installed; pip install"):
        build_plant({"type": "mujoco"})


def test_armature_adds_to_each_joints_inertia_and_is_checked_per_joint() -> None:
    prep = panda()
    gains = []
    for armature in (0.0, 0.1, [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7]):
        plant = build_plant({"type": "mujoco", "frequency": 10.0, "armature": armature})
        plant.reset(prep.robot, prep.q0, prep.dt)
        gains.append(plant.body.kp / (2.0 * np.pi * 10.0) ** 2)  # M_ii + I_a [kg·m²]
    np.testing.assert_allclose(gains[1] - gains[0], 0.1, rtol=1e-9)
    np.testing.assert_allclose(gains[2] - gains[0], np.arange(1, 8) / 10.0, rtol=1e-9)
    with pytest.raises(ConfigError) as info:
        check_plant({"type": "mujoco", "armature": [0.1, 0.1]}, prep.robot, prep.q0, prep.dt, "p")
    assert "armature" in str(info.value) and "\n" not in str(info.value)


def test_the_command_low_pass_filters_every_step_and_keeps_the_rest_point() -> None:
    """``command_cutoff``: libfranka's first-order filter at the MuJoCo rate. The reference it
    integrates ends where the raw commands' integral does (unit DC gain); the velocity servo
    no longer sees a command's step whole; bad cutoffs are one line."""
    prep = panda()
    nv = prep.robot.nv
    for cutoff, timestep in ((100.0, 0.001), (5.0, 0.002)):
        plant = build_plant({"type": "mujoco", "command_cutoff": cutoff, "timestep": timestep})
        body = plant.body
        plant.reset(prep.robot, prep.q0, prep.dt)
        start = body._reference.copy()
        command = np.linspace(-0.3, 0.3, nv)
        q = prep.q0
        q = plant.advance(q, command).q
        h = prep.dt / body.substeps
        beta = 2 * np.pi * cutoff * h / (2 * np.pi * cutoff * h + 1)
        expected = command * (1 - (1 - beta) ** body.substeps)  # the filter after one period
        np.testing.assert_allclose(body._filtered, expected, rtol=1e-12)
        for _ in range(200):  # zero commands: the filter drains, the reference comes to rest
            q = plant.advance(q, np.zeros(nv)).q
        np.testing.assert_allclose(body._reference - start, command * prep.dt, rtol=1e-6)
    declared = build_plant({"type": "mujoco", "command_cutoff": 100.0}).declares(prep.dt)
    assert declared.lags == (pytest.approx(1 / (2 * np.pi * 100.0)),)
    assert "cutoff=100" in build_plant({"type": "mujoco", "command_cutoff": 100.0}).label()
    for bad in (0.0, -5.0, float("nan"), "fast"):
        with pytest.raises(ConfigError) as info:
            build_plant({"type": "mujoco", "command_cutoff": bad})
        assert "command_cutoff" in str(info.value) and "\n" not in str(info.value)
