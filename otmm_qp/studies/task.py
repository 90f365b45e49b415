"""Which task of a study, and how it is built: the one builder of a study task.

A :class:`StudyTask` is a task's identity (robot, generator entry, index, seed);
:meth:`StudyTask.build` makes its robot, task weight, :class:`~otmm_qp.scenarios.generator.Task`
and episode duration (:func:`episode_duration`, the one duration rule). The plan's dry run,
the worker, the drill-down and the trade-off build tasks only through it, so they cannot
disagree; :meth:`StudyTask.of_row` finds the task of a stored episode row.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from otmm_qp import registry
from otmm_qp.exceptions import ConfigError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.scenarios.generator import Task, TaskGenerator
from otmm_qp.simulation.episode import Episode, Loop
from otmm_qp.studies.schema import StudyConfig
from otmm_qp.studies.task_ids import entry_label

if TYPE_CHECKING:
    from otmm_qp.config.schema import ControllerConfig


def episode_duration(config: StudyConfig, task: Task) -> float:
    """The task's duration plus the study's ``duration.extra``, capped at ``duration.max`` [s]."""
    duration = task.duration + config.duration.extra
    if config.duration.max is not None:
        duration = min(duration, config.duration.max)
    return duration


def plant_name(config: ControllerConfig) -> str:
    """The ``plants`` label of an expanded controller (``ideal`` without a plants axis)."""
    if config.plant is None:
        return "ideal"
    return config.name.rsplit("@", 1)[1] if "@" in config.name else "controller's own"


@dataclass
class BuildCache:
    """Robots and generators built once (per process), keyed by their spec.

    Attributes:
        robots: Robot by the JSON of its spec.
        generators: Generator by the JSON of its entry (type and parameters).
    """

    robots: dict[str, Robot] = field(default_factory=dict)
    generators: dict[str, TaskGenerator] = field(default_factory=dict)

    @staticmethod
    def robot_key(config: StudyConfig, index: int) -> str:
        """The cache key of robot ``index``."""
        return json.dumps(config.robots[index].robot.model_dump(mode="json"), sort_keys=True)

    @staticmethod
    def generator_key(config: StudyConfig, index: int) -> str:
        """The cache key of generator entry ``index``."""
        spec = config.generators[index]
        return json.dumps({"type": spec.type, **spec.params}, sort_keys=True, default=str)

    def robot(self, config: StudyConfig, index: int) -> Robot:
        """Robot ``index`` of the study (built on first use)."""
        key = self.robot_key(config, index)
        if key not in self.robots:
            spec = config.robots[index].robot
            self.robots[key] = registry.create(
                registry.ROBOTS, spec.type, spec.params, f"robots.{index}.robot"
            )
        return self.robots[key]

    def generator(self, config: StudyConfig, index: int) -> TaskGenerator:
        """Generator entry ``index`` of the study (built on first use)."""
        key = self.generator_key(config, index)
        if key not in self.generators:
            spec = config.generators[index]
            self.generators[key] = registry.create(
                registry.TASK_GENERATORS, spec.type, spec.params, f"generators.{index}"
            )
        return self.generators[key]


@dataclass(frozen=True)
class BuiltTask:
    """A study task, built.

    Attributes:
        robot: The robot.
        weight: Its diagonal task weight, shape ``(n,)``, or None.
        task: The task (start, motion, duration, descriptors).
        duration: The episode duration [s] (:func:`episode_duration`).
    """

    robot: Robot
    weight: FloatArray | None
    task: Task
    duration: float


@dataclass(frozen=True)
class StudyTask:
    """The identity of one study task.

    Attributes:
        robot: Robot index in the study.
        generator: Generator entry index.
        index: Task index within the entry.
        seed: Task seed (``task_seed``).
    """

    robot: int
    generator: int
    index: int
    seed: int

    def build(self, config: StudyConfig, cache: BuildCache | None = None) -> BuiltTask:
        """The robot, weight, task and episode duration, as every part of a study builds them.

        Raises:
            Exception: Whatever the robot or generator raises (the worker stores it in the row).
        """
        cache = BuildCache() if cache is None else cache
        robot = cache.robot(config, self.robot)
        spec = config.robots[self.robot]
        weight = np.asarray(spec.task_weight, dtype=float) if spec.task_weight else None
        task = cache.generator(config, self.generator).generate(robot, self.seed, weight)
        return BuiltTask(robot, weight, task, episode_duration(config, task))

    @classmethod
    def of_row(cls, config: StudyConfig, row: Mapping[str, Any]) -> StudyTask:
        """The task of a stored episode row (robot by name, entry by its label).

        Rows written before ``generator_entry`` was stored are matched by generator type and
        parameters.

        Raises:
            ConfigError: The row's robot or generator entry is not in the study.
        """
        robots = [r.name for r in config.robots]
        if row.get("robot") not in robots:
            raise ConfigError("study.json", f"robot {row.get('robot')!r:.60} is not in the study")
        labels = [entry_label(config, j) for j in range(len(config.generators))]
        if row.get("generator_entry") in labels:
            generator = labels.index(str(row["generator_entry"]))
        else:
            generator = _entry_by_params(config, row)
        robot = robots.index(str(row["robot"]))
        return cls(robot, generator, int(row["task_index"]), int(row["task_seed"]))


#: What a planned episode runs: one of the study's controllers, or the task's reference.
EpisodeKind = Literal["controller", "reference"]
#: :attr:`PlannedEpisode.kind` of an episode that runs one of the study's controllers.
CONTROLLER: EpisodeKind = "controller"
#: :attr:`PlannedEpisode.kind` of a task's offline-optimal reference episode.
REFERENCE: EpisodeKind = "reference"
#: The loop mode of a reference episode (it sees the whole path, solved offline).
OFFLINE = "offline"


@dataclass(frozen=True)
class PlannedEpisode:
    """One episode of a study plan: a task, what runs on it, and the episode's key.

    A task's offline-optimal reference is an episode too: ``kind = REFERENCE``, no controller
    index and loop mode :data:`OFFLINE`; a controller episode has ``kind = CONTROLLER`` and
    the index of its controller in ``StudyPlan.controllers``. Checked on construction.

    Attributes:
        key: The episode key (SHA-256 of everything that sets its numbers, see ``spec``).
        task: Which task (robot, generator entry, index, seed).
        kind: :data:`CONTROLLER` or :data:`REFERENCE`.
        loop_mode: ``open`` or ``clik`` (:data:`OFFLINE` for the reference).
        controller: Index into the plan's controllers; None for the reference.

    Raises:
        ValueError: A kind other than the two, a reference with a controller index or a loop
            mode other than offline, or a controller episode without a valid index.
    """

    key: str
    task: StudyTask
    kind: EpisodeKind
    loop_mode: str
    controller: int | None = None

    def __post_init__(self) -> None:
        if self.kind == REFERENCE:
            if self.controller is not None or self.loop_mode != OFFLINE:
                raise ValueError(
                    f"a reference episode has no controller index and loop mode {OFFLINE!r}, "
                    f"got controller={self.controller!r}, loop_mode={self.loop_mode!r}"
                )
        elif self.kind == CONTROLLER:
            if not isinstance(self.controller, int) or self.controller < 0:
                raise ValueError(
                    f"a controller episode needs a controller index >= 0, got {self.controller!r}"
                )
        else:
            raise ValueError(f"kind: {self.kind!r}; use {CONTROLLER!r} or {REFERENCE!r}")

    @classmethod
    def reference(cls, key: str, task: StudyTask) -> PlannedEpisode:
        """The task's reference episode."""
        return cls(key, task, REFERENCE, OFFLINE)

    @classmethod
    def of_controller(
        cls, key: str, task: StudyTask, controller: int, loop_mode: str
    ) -> PlannedEpisode:
        """Controller ``controller``'s episode on ``task`` in ``loop_mode``."""
        return cls(key, task, CONTROLLER, loop_mode, controller)

    @property
    def is_reference(self) -> bool:
        """Whether this is the task's offline reference."""
        return self.kind == REFERENCE

    @property
    def robot(self) -> int:
        """Robot index of the task."""
        return self.task.robot

    @property
    def generator(self) -> int:
        """Generator entry index of the task."""
        return self.task.generator

    @property
    def task_index(self) -> int:
        """Index of the task within its generator entry."""
        return self.task.index

    @property
    def seed(self) -> int:
        """Seed the task is drawn from."""
        return self.task.seed


def study_episode(config: StudyConfig, built: BuiltTask, mode: str) -> Episode:
    """The :class:`Episode` of a built task in one loop mode (checked like every run's).

    Raises:
        OtmmError: The task's start is outside the joint limits, or a value out of range.
    """
    robot, task = built.robot, built.task
    return Episode(
        robot,
        task.trajectory,
        robot.check_start(task.q0),
        config.dt,
        built.duration,
        Loop(mode, config.clik_gain),  # type: ignore[arg-type]
        built.weight,
        config.name,
        config.max_steps,
    )


def _entry_by_params(config: StudyConfig, row: Mapping[str, Any]) -> int:
    params = json.loads(str(row.get("generator_params") or "{}"))
    for j, gen in enumerate(config.generators):
        same = json.loads(json.dumps(gen.params, sort_keys=True, default=str)) == params
        if gen.type == row.get("generator") and same:
            return j
    raise ConfigError(
        "study.json",
        f"generator {row.get('generator')!r:.40} {str(params):.80} of the row is not in the study",
    )
