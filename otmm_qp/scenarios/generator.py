"""The task-generator interface: ``(robot, seed) → Task``, reproducible from its inputs."""

from __future__ import annotations

import abc
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from otmm_qp.exceptions import OtmmError, ParameterError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.trajectories.trajectory import Trajectory

Descriptor = float | int | str


class TaskGenerationError(OtmmError):
    """A generator could not build a task within its budget.

    Attributes:
        generator: Generator name.
        robot: Robot name.
        reason: What ran out.
    """

    def __init__(self, generator: str, robot: str, reason: str) -> None:
        self.generator = generator
        self.robot = robot
        self.reason = reason
        super().__init__(f"generator {generator!r} on robot {robot!r}: {reason}")


@dataclass
class Task:
    """One study task: where the arm starts and what it must follow.

    Attributes:
        q0: Start joint coordinates [rad or m], shape ``(nv,)`` (inside the limits).
        trajectory: Desired motion, built with ``start = f(q0)``.
        duration: Natural duration of the motion [s].
        descriptors: Scalars describing the task (e.g. ``sigma_min_closest``), stored with
            every episode run on it.
    """

    q0: FloatArray
    trajectory: Trajectory
    duration: float
    descriptors: dict[str, Descriptor] = field(default_factory=dict)


def task_seed(study_seed: int, robot: str, generator: str, index: int) -> int:
    """Seed of task ``index`` of ``generator`` on ``robot``: stable across runs and machines.

    Built from a :class:`numpy.random.SeedSequence` over the study seed, CRC-32 of the two
    names and the index (Python's ``hash`` is salted per process, so it is not used).
    """
    entropy = [int(study_seed), zlib.crc32(robot.encode()), zlib.crc32(generator.encode()), index]
    return int(np.random.SeedSequence(entropy).generate_state(1, dtype=np.uint32)[0])


def check_range(name: str, value: Sequence[float], lower: float = 0.0) -> tuple[float, float]:
    """Validate a ``[low, high]`` parameter with ``lower ≤ low ≤ high``.

    Raises:
        ParameterError: Naming the parameter.
    """
    pair = tuple(float(v) for v in value)
    if len(pair) != 2 or not (lower <= pair[0] <= pair[1]) or not np.all(np.isfinite(pair)):
        raise ParameterError(
            name, f"must be [low, high] with {lower:g} <= low <= high, got {value}"
        )
    return pair[0], pair[1]


def check_duration(value: Sequence[float]) -> tuple[float, float]:
    """Validate a ``duration: [low, high]`` [s] parameter: :func:`check_range` with ``low > 0``.

    Raises:
        ParameterError: Naming ``duration``.
    """
    pair = check_range("duration", value)
    if not pair[0] > 0.0:
        raise ParameterError("duration", f"must be > 0 [s], got {list(value)}")
    return pair


def draw(rng: np.random.Generator, bounds: tuple[float, float]) -> float:
    """Uniform draw in ``[low, high]`` (the value itself when ``low == high``)."""
    return float(rng.uniform(bounds[0], bounds[1])) if bounds[1] > bounds[0] else bounds[0]


class TaskGenerator(abc.ABC):
    """Draws tasks for a robot. Plugins are built as ``Generator(**params)``.

    A task must depend only on the robot, the generator's parameters and the seed, so that
    every executor (and a later ``--resume``) rebuilds the very same task.
    """

    name: str = "generator"

    @abc.abstractmethod
    def generate(self, robot: Robot, seed: int, task_weight: FloatArray | None = None) -> Task:
        """Draw the task of ``seed`` for ``robot``.

        Args:
            robot: The arm.
            seed: Task seed (see :func:`task_seed`).
            task_weight: Diagonal task weight used for σ_min, shape ``(n,)``.

        Raises:
            TaskGenerationError: The generator's budget ran out (naming the robot).
        """
