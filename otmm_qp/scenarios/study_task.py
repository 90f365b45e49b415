"""The motion of one study task, rebuilt from its generator, parameters and seed.

``{type: study_task, robot: {type, ...}, generator: {type, ...}, seed: N}`` regenerates the
task exactly as the study's worker did (a task depends only on robot, generator parameters
and seed), so ``otmm-qp run`` on the config ``otmm-qp study show`` writes reproduces the
stored episode bit for bit.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from numbers import Integral, Real
from typing import Any, ClassVar

import numpy as np

from otmm_qp import registry
from otmm_qp.exceptions import ConfigError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.scenarios.generator import Task
from otmm_qp.trajectories.trajectory import Trajectory
from otmm_qp.validation import ArrayOf, Constraints, InstanceOf, Interval

#: Largest distance [task units] between the run's start pose and the task's start.
START_TOLERANCE = 1e-9


def _spec(value: Mapping[str, Any], field: str) -> tuple[str, dict[str, Any]]:
    if not isinstance(value, Mapping) or not isinstance(value.get("type"), str):
        raise ConfigError(field, "must be a mapping {type: NAME, ...parameters}")
    params = {k: v for k, v in value.items() if k != "type"}
    return str(value["type"]), params


def generate_task(
    robot: Mapping[str, Any],
    generator: Mapping[str, Any],
    seed: int,
    task_weight: Sequence[float] | None = None,
) -> tuple[Robot, Task]:
    """The robot and task ``seed`` of a generator entry (the study worker's own calls).

    Raises:
        ConfigError: A bad spec or seed.
        TaskGenerationError: The generator's budget ran out.
    """
    robot_type, robot_params = _spec(robot, "robot")
    generator_type, generator_params = _spec(generator, "generator")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ConfigError("seed", f"must be an integer >= 0, got {seed!r}")
    arm: Robot = registry.create(registry.ROBOTS, robot_type, robot_params, "robot")
    source = registry.create(
        registry.TASK_GENERATORS, generator_type, generator_params, "generator"
    )
    weight = None if task_weight is None else np.asarray(task_weight, dtype=float)
    return arm, source.generate(arm, seed, weight)


class StudyTaskTrajectory(Trajectory):
    """The trajectory of task ``seed`` of a study generator on a robot.

    Args:
        start: Task value at the run's start configuration (must be the task's start).
        robot: The study robot's plugin spec ``{type, **params}``.
        generator: The generator entry ``{type, **params}`` (without ``count``).
        seed: The task seed stored with the episode (``task_seed`` column).
        task_weight: The study robot's diagonal task weight, shape ``(n,)``, or None.

    Raises:
        ConfigError: A bad spec, or a start that is not the task's start (wrong ``q0``).
    """

    name = "study_task"

    parameter_constraints: ClassVar[Constraints] = {
        "robot": InstanceOf((Mapping,), "a robot record {type: NAME, ...}"),
        "generator": InstanceOf((Mapping,), "a generator record {type: NAME, ...}"),
        "seed": Interval(Integral, 0, None),
        "task_weight": [ArrayOf(Interval(Real, 0, None), per="task row"), None],
    }

    def __init__(
        self,
        start: FloatArray,
        robot: Mapping[str, Any],
        generator: Mapping[str, Any],
        seed: int,
        task_weight: Sequence[float] | None = None,
    ) -> None:
        arm, task = generate_task(robot, generator, seed, task_weight)
        self._motion = task.trajectory
        self.lookahead = task.trajectory.lookahead  # the task's own information class
        self.duration = float(task.duration)
        self.q0 = np.asarray(task.q0, dtype=float)
        expected = np.asarray(arm.forward(arm.configuration(self.q0)), dtype=float)
        given = np.asarray(start, dtype=float)
        if given.shape != expected.shape or not np.allclose(
            given, expected, rtol=0.0, atol=START_TOLERANCE
        ):
            raise ConfigError(
                "start", f"the run does not start at the task's q0 {np.round(self.q0, 6).tolist()}"
            )

    def sample(self, t: float) -> tuple[FloatArray, FloatArray]:
        """The task's desired value and velocity at ``t`` [s]."""
        return self._motion.sample(t)
