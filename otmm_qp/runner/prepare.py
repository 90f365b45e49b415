"""One ``prepare``: every check a run needs before any compute, shared by ``run`` and ``study``.

:func:`make_episode` turns raw inputs into an :class:`~otmm_qp.simulation.episode.Episode`
(its own checks, shaped as :class:`~otmm_qp.exceptions.ConfigError` on the config field);
:func:`prepare` adds the checks that need the built objects: finite kinematics at ``q0``,
the workspace (optional: study tasks may be unreachable by design) and one dry-run step of
every controller on a copy. :func:`prepare_experiment` is both for one experiment of a suite.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from otmm_qp.conditioning.pipeline import Conditioning, build_conditioning
from otmm_qp.config.schema import ExperimentConfig, SuiteConfig
from otmm_qp.controller import Controller
from otmm_qp.exceptions import ConfigError, DimensionError
from otmm_qp.plants.chain import PlantChain, build_plant
from otmm_qp.plants.declaration import PlantDeclaration
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.runner.build import (
    SkippedController,
    build_controllers,
    build_trajectory,
    check_controllers,
    check_reachable,
    check_robot,
    load_robot,
    start_configuration,
)
from otmm_qp.runner.plant_stage import experiment_stages, plant_declarations
from otmm_qp.simulation.episode import Episode, Loop
from otmm_qp.simulation.loop_modes import LoopMode
from otmm_qp.trajectories.trajectory import Trajectory


@dataclass(frozen=True)
class PreparedExperiment:
    """An experiment ready to run: one checked episode per loop mode, and its controllers.

    Attributes:
        config: The experiment record.
        episodes: One :class:`Episode` per loop mode, in config order (same robot, start,
            trajectory, ``dt`` and duration).
        controllers: Controllers in config order.
        skipped: Controllers whose peer library is missing (reported, never run).
        plants: Plant config per controller name (``{type, ...}`` or a list; absent: ideal).
        conditioning: Conditioning stages per controller name (absent: none).
    """

    config: ExperimentConfig
    episodes: tuple[Episode, ...]
    controllers: list[Controller]
    skipped: list[SkippedController] = field(default_factory=list)
    plants: dict[str, Any] = field(default_factory=dict)
    conditioning: dict[str, list[dict[str, Any]]] = field(default_factory=dict)

    def build_stage(self, controller: str) -> tuple[PlantChain, Conditioning]:
        """A fresh plant and the conditioning of ``controller`` for one run (both stateful)."""
        return (
            build_plant(self.plants.get(controller)),
            build_conditioning(self.conditioning.get(controller)),
        )

    @property
    def robot(self) -> Robot:
        """The arm."""
        return self.episodes[0].robot

    @property
    def q0(self) -> FloatArray:
        """Start configuration, shape ``(nq,)``."""
        return self.episodes[0].q0

    @property
    def trajectory(self) -> Trajectory:
        """Desired motion."""
        return self.episodes[0].trajectory

    @property
    def dt(self) -> float:
        """Control period [s]."""
        return self.episodes[0].dt

    @property
    def duration(self) -> float:
        """Simulated time [s]."""
        return self.episodes[0].duration

    @property
    def loop_modes(self) -> list[LoopMode]:
        """Loop modes, in config order."""
        return [e.loop.mode for e in self.episodes]

    @property
    def task_weight(self) -> FloatArray | None:
        """Diagonal task weight, shape ``(n,)``, or None."""
        return self.episodes[0].task_weight


def make_episode(
    field_path: str, duration_field: str, loop_mode: str, clik_gain: float, **values: object
) -> Episode:
    """``Episode(loop=Loop(loop_mode, clik_gain), **values)``, errors shaped as ConfigError.

    Args:
        field_path: Config path of the experiment (or study episode) the values come from.
        duration_field: Config path blamed for ``duration`` and the step cap.
        loop_mode: ``feedforward``, ``clik`` or ``newton``.
        clik_gain: CLIK gain K [1/s].
        **values: The other :class:`Episode` fields.

    Raises:
        ConfigError: ``dt``, ``duration``, ``clik_gain``, ``loop_mode``, ``task_weight`` or
            the step cap, naming the field.
    """
    try:
        loop = Loop(loop_mode, clik_gain)  # type: ignore[arg-type]
        return Episode(loop=loop, **values)  # type: ignore[arg-type]
    except DimensionError as error:
        raise ConfigError(
            f"{field_path}.{error.name}", f"expected shape {error.expected}, got {error.got}"
        ) from None
    except ConfigError as error:
        where = duration_field if error.field == "duration" else f"{field_path}.{error.field}"
        raise ConfigError(where, error.message) from None


def prepare(
    episode: Episode,
    controllers: list[Controller],
    field_path: str,
    *,
    reachable: bool = True,
    declarations: Mapping[str, Sequence[PlantDeclaration]] | None = None,
) -> None:
    """Every check that needs the built objects, before any compute.

    Args:
        episode: The episode (already self-checked).
        controllers: Controllers that will run it (each dry-run once on a copy).
        field_path: Config path named in errors.
        reachable: Also require every trajectory sample inside the workspace.
        declarations: What the plants each controller runs under declare, by controller
            name (handed to its dry run); None: nothing declared.

    Raises:
        ConfigError: Non-finite kinematics or NaN limits, an unreachable trajectory, or a
            controller whose parameters do not fit the robot.
    """
    check_robot(episode.robot, episode.q0, field_path)
    if reachable:
        check_reachable(
            episode.robot, episode.trajectory, episode.duration, f"{field_path}.trajectory"
        )
    check_controllers(controllers, episode, field_path, declarations)


def prepare_experiment(
    suite: SuiteConfig, index: int, source: str = "config", max_steps: int | None = None
) -> PreparedExperiment:
    """Build and check experiment ``index`` of ``suite``.

    Raises:
        ConfigError: Any bad input, with the config path of the field at fault.
    """
    config = suite.experiments[index]
    field_path = f"{source}: experiments.{index}"
    robot = load_robot(config.robot, f"{field_path}.robot")
    q0 = start_configuration(robot, config, field_path)
    trajectory = build_trajectory(config, field_path, robot.forward(q0), robot, q0)
    duration = config.duration if config.duration is not None else trajectory.duration
    duration_field = (
        f"{field_path}.duration" if config.duration is not None else f"{field_path}.trajectory"
    )
    if not math.isfinite(duration) or duration <= 0.0:
        raise ConfigError(duration_field, f"duration must be finite and > 0, got {duration:.3g}")
    gain = config.clik_gain if config.clik_gain is not None else suite.clik_gain
    episodes = tuple(
        make_episode(
            field_path,
            duration_field,
            robot=robot,
            trajectory=trajectory,
            q0=q0,
            dt=config.dt if config.dt is not None else suite.dt,
            duration=duration,
            loop_mode=mode,
            clik_gain=gain,
            task_weight=config.task_weight,
            name=config.name,
            max_steps=suite.max_steps if max_steps is None else max_steps,
        )
        for mode in (config.loop_modes or suite.loop_modes)
    )
    controllers, skipped = build_controllers(config, field_path, suite.metrics.blow_up_speed)
    plants, conditioning = experiment_stages(
        config.plant if config.plant is not None else suite.plant,
        config.controllers, robot, episodes[0].q0, episodes[0].dt, field_path,
        (max(e.steps for e in episodes), episodes[0].max_steps),
    )  # fmt: skip
    declarations = {
        name: plant_declarations([record], episodes[0].dt) for name, record in plants.items()
    }
    # out_of_reach: the config knows the trajectory leaves the workspace (a study's task)
    prepare(
        episodes[0], controllers, field_path, reachable=not config.out_of_reach,
        declarations=declarations,
    )  # fmt: skip
    return PreparedExperiment(config, episodes, controllers, skipped, plants, conditioning)
