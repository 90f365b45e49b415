"""Three plants-study episodes whose joints left their limits under ``qp``'s ``predicted_position``
because of the plant model, not the controller: each violates with the old model and keeps every
limit with the plants study's (``contacts: false``; the presets' 0.1 kg·m² armature).

* UR5, ``near_singular`` task 2 of ``configs/studies/plants.yaml``: its start is in
  self-collision (forearm against wrist 2 by ~1.7 cm); with contacts the first step kicks
  wrist 2 past its limit and the contact holds it there against its 28 N·m.
* Panda, ``beyond_reach`` task 1 under ``ur_e_series``: without armature the URDF mass matrix
  (condition number ~800) lets the decentralised servos chatter at the torque limits under a
  near-zero command (joint 5 at ±3–5 rad/s); with the armature they track.
* UR5, ``beyond_reach`` task 3 under ``franka_fci``: without libfranka's rate limiter (the
  preset before it) the 100 Hz servo falls behind accelerations the torques cannot give and
  drags a joint past its limit; with it the limit holds (the interface, not the body: the
  ``predicted_position`` limit models the limiter the plant declares).
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

pytest.importorskip("mujoco")

from otmm_qp.conditioning import Conditioning  # noqa: E402
from otmm_qp.metrics.metrics import MetricSettings  # noqa: E402
from otmm_qp.plants import build_plant  # noqa: E402
from otmm_qp.plants.presets import ARMATURE, PRESETS  # noqa: E402
from otmm_qp.runner.build import build_controller  # noqa: E402
from otmm_qp.runner.episode import run_episode  # noqa: E402
from otmm_qp.scenarios.generator import task_seed  # noqa: E402
from otmm_qp.simulation.run_result import RunResult  # noqa: E402
from otmm_qp.studies.schema import StudyConfig  # noqa: E402
from otmm_qp.studies.spec import expand_controllers, load_study  # noqa: E402
from otmm_qp.studies.task import BuiltTask, StudyTask, study_episode  # noqa: E402
from otmm_qp.studies.task_ids import seed_name  # noqa: E402

STUDY = "configs/studies/plants.yaml"


@cache
def study() -> StudyConfig:
    return load_study(STUDY)


@cache
def task(robot: str, generator: str, index: int) -> BuiltTask:
    config = study()
    r = next(i for i, spec in enumerate(config.robots) if spec.name == robot)
    g = next(i for i, gen in enumerate(config.generators) if gen.type == generator)
    seed = task_seed(config.seed, robot, seed_name(config, g), index)
    return StudyTask(r, g, index, seed).build(config)


def run_qp(built: BuiltTask, plant: object) -> RunResult:
    """The study's ``qp`` (default ``predicted_position``) on ``built`` under ``plant``."""
    config = study()
    spec = next(c for c in expand_controllers(config, STUDY) if c.name == "qp@ideal")
    settings = MetricSettings(**config.metrics.model_dump())
    made = build_controller(spec, "controllers.qp", settings.blow_up_speed)
    episode = study_episode(config, built, "clik")
    record = run_episode(episode, made, settings, (build_plant(plant), Conditioning()))
    assert record.result.error_message is None
    return record.result


def outside(result: RunResult) -> float:
    """Largest distance [rad] of the true q past a joint limit over the run (≤ 0: inside)."""
    lower, upper = result.position_limits
    return float(np.max(np.maximum(lower - result.q, result.q - upper)))


def test_a_start_in_self_collision_no_longer_throws_a_joint_past_its_limit() -> None:
    built = task("ur5", "near_singular", 2)
    body = {"type": "mujoco", "frequency": 10.0, "damping_ratio": 1.0, "timestep": 0.002}
    colliding = run_qp(built, body)  # contacts on: the default
    assert outside(colliding) > 0.01  # wrist 2 past its limit by more than 10 mrad
    kept = run_qp(built, {**body, "contacts": False})
    assert outside(kept) <= 0.0


def test_the_presets_armature_stops_the_servo_chatter_that_passed_a_limit() -> None:
    built = task("panda", "beyond_reach", 1)
    preset = [dict(stage) for stage in PRESETS["ur_e_series"]]
    assert preset[-1]["armature"] == ARMATURE
    bare = [*preset[:-1], {**preset[-1], "armature": 0.0}]
    chattering = run_qp(built, bare)
    assert outside(chattering) > 1e-3
    assert int(np.sum(chattering.saturated)) > 50  # torque-limited most of the run
    kept = run_qp(built, {"preset": "ur_e_series"})
    assert outside(kept) <= 0.0


def test_the_franka_rate_limiter_keeps_the_limit_the_torques_could_not() -> None:
    """UR5 ``beyond_reach`` task 3 under ``franka_fci``: without libfranka's rate limiter the
    commanded accelerations outrun the torques and the servo drags a joint past its limit (even
    behind the 100 Hz command filter); with it (and ``predicted_position`` modelling it, read
    from the plant) every limit holds."""
    built = task("ur5", "beyond_reach", 3)
    preset = [dict(stage) for stage in PRESETS["franka_fci"]]
    assert preset[0]["type"] == "rate_limit"
    unlimited = run_qp(built, preset[1:])
    assert outside(unlimited) > 1e-2
    assert bool(np.any(unlimited.saturated))
    kept = run_qp(built, {"preset": "franka_fci"})
    assert outside(kept) <= 0.0
