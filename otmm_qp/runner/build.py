"""Turn validated config records into robots, trajectories and controllers."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from otmm_qp import registry
from otmm_qp.config.schema import ControllerConfig, ExperimentConfig, SuiteConfig
from otmm_qp.controller import Controller
from otmm_qp.exceptions import ConfigError, DimensionError, OtmmError, PeerUnavailable
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.simulation.loop_modes import LoopMode
from otmm_qp.simulation.simulate import task_position
from otmm_qp.trajectories.trajectory import Trajectory

#: Trajectory samples checked against the workspace before running.
REACH_SAMPLES = 200


@dataclass(frozen=True)
class SkippedController:
    """A controller left out because an optional peer library is not installed.

    Attributes:
        name: Controller label.
        filters: Filter types joined by ``+`` (``none`` when there are none).
        backend: Backend type.
        reason: ``peer '...' is not installed; pip install ...``.
    """

    name: str
    filters: str
    backend: str
    reason: str


@dataclass
class PreparedExperiment:
    """An experiment ready to run: every object built and every input checked.

    Attributes:
        config: The experiment record.
        robot: The arm.
        q0: Start configuration, shape ``(nq,)``.
        trajectory: Desired motion.
        controllers: Controllers in config order.
        dt: Control period [s].
        duration: Simulated time [s].
        loop_modes: Loop modes to run.
        clik_gain: CLIK gain [1/s].
        task_weight: Diagonal task weight, shape ``(n,)``, or None.
        skipped: Controllers whose peer library is missing (reported, never run).
    """

    config: ExperimentConfig
    robot: Robot
    q0: FloatArray
    trajectory: Trajectory
    controllers: list[Controller]
    dt: float
    duration: float
    loop_modes: list[LoopMode]
    clik_gain: float
    task_weight: FloatArray | None
    skipped: list[SkippedController] = field(default_factory=list)


def build_controller(config: ControllerConfig, field: str) -> Controller:
    """Instantiate the filters and backend of a controller record.

    Raises:
        ConfigError: Unknown plugin name or parameter, or a value out of range.
    """
    filters = []
    for j, spec in enumerate(config.filters):
        task_filter = registry.create(
            registry.FILTERS, spec.type, spec.params, f"{field}.filters.{j}"
        )
        task_filter.name = spec.type
        filters.append(task_filter)
    backend = registry.create(
        registry.BACKENDS, config.backend.type, config.backend.params, f"{field}.backend"
    )
    backend.name = config.backend.type
    return Controller(config.name, filters, backend)


def check_reachable(robot: Robot, trajectory: Trajectory, duration: float, field: str) -> None:
    """Reject a trajectory that leaves the arm's workspace.

    Raises:
        ConfigError: Naming the first unreachable point and its time.
    """
    for t in np.linspace(0.0, duration, REACH_SAMPLES):
        x = trajectory.position(float(t))
        if not robot.can_reach(x):
            point = np.round(task_position(np.asarray(x)), 4).tolist()
            raise ConfigError(
                field, f"point {point} at t = {t:.3g} s is outside the workspace of {robot.name}"
            )


def prepare_experiment(
    suite: SuiteConfig, index: int, source: str = "config"
) -> PreparedExperiment:
    """Build and check experiment ``index`` of ``suite``.

    Raises:
        ConfigError: Any bad input, with the config path of the field at fault.
    """
    config = suite.experiments[index]
    field = f"{source}: experiments.{index}"
    robot: Robot = registry.create(
        registry.ROBOTS, config.robot.type, config.robot.params, f"{field}.robot"
    )
    try:
        q0 = robot.check_start(np.asarray(config.q0, dtype=float))
    except OtmmError as error:
        message = str(error).removeprefix("q0: ")
        raise ConfigError(f"{field}.q0", message) from error
    weight = None
    if config.task_weight is not None:
        weight = np.asarray(config.task_weight, dtype=float)
        if weight.shape != (robot.task_dim,):
            raise ConfigError(
                f"{field}.task_weight",
                f"expected shape {(robot.task_dim,)}, got {weight.shape}",
            )
    x0 = robot.forward(q0)
    trajectory: Trajectory = registry.create(
        registry.TRAJECTORIES,
        config.trajectory.type,
        config.trajectory.params,
        f"{field}.trajectory",
        start=x0,
    )
    trajectory.name = config.trajectory.type
    duration = config.duration if config.duration is not None else trajectory.duration
    check_reachable(robot, trajectory, duration, f"{field}.trajectory")
    controllers, skipped = _build_controllers(config, field)
    return PreparedExperiment(
        config=config,
        robot=robot,
        q0=q0,
        trajectory=trajectory,
        controllers=controllers,
        dt=config.dt if config.dt is not None else suite.dt,
        duration=duration,
        loop_modes=list(config.loop_modes or suite.loop_modes),
        clik_gain=config.clik_gain if config.clik_gain is not None else suite.clik_gain,
        task_weight=weight,
        skipped=skipped,
    )


def _build_controllers(
    config: ExperimentConfig, field: str
) -> tuple[list[Controller], list[SkippedController]]:
    """Build every controller; one whose peer library is missing is skipped, not fatal."""
    controllers: list[Controller] = []
    skipped: list[SkippedController] = []
    for j, spec in enumerate(config.controllers):
        try:
            controllers.append(build_controller(spec, f"{field}.controllers.{j}"))
        except PeerUnavailable as error:
            filters = "+".join(f.type for f in spec.filters) or "none"
            skipped.append(SkippedController(spec.name, filters, spec.backend.type, str(error)))
    return controllers, skipped
