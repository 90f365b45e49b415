"""Turn validated config records into robots, trajectories and controllers."""

from __future__ import annotations

import contextlib
import copy
import math
import os
import sys
import tempfile
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from otmm_qp import registry
from otmm_qp.config.schema import ControllerConfig, ExperimentConfig, SuiteConfig
from otmm_qp.controller import Controller
from otmm_qp.exceptions import (
    ConfigError,
    DimensionError,
    OtmmError,
    PeerUnavailable,
    UnreachableTrajectory,
)
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.simulation.loop_modes import LoopMode
from otmm_qp.simulation.simulate import task_position
from otmm_qp.state import KinematicState
from otmm_qp.status import DIVERGENCE_SPEED
from otmm_qp.trajectories.trajectory import Trajectory

#: Trajectory samples checked against the workspace before running.
REACH_SAMPLES = 200
#: Largest |joint coordinate| accepted in ``q0`` [rad or m]: beyond it trigonometry is noise.
MAX_JOINT_COORDINATE = 1.0e4
#: Bytes logged per step and joint/task coordinate (time series of floats), for the cap message.
_BYTES_PER_VALUE = 8


def _short(value: object, limit: int = 120) -> str:
    """``str(value)`` cut to ``limit`` characters (error messages never embed unbounded data)."""
    text = str(value).replace("\n", " ")
    return text if len(text) <= limit else text[: limit - 3] + "..."


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


def build_controller(
    config: ControllerConfig, field: str, divergence_speed: float = DIVERGENCE_SPEED
) -> Controller:
    """Instantiate the filters and backend of a controller record.

    ``divergence_speed`` [rad/s] is the experiment's ``metrics.blow_up_speed``, so a step is
    reported ``diverging`` exactly where the ``blow_up`` metric counts it.

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
    return Controller(config.name, filters, backend, divergence_speed)


def check_reachable(
    robot: Robot, trajectory: Trajectory, duration: float, field: str, workspace: bool = True
) -> None:
    """Reject a trajectory that leaves the arm's workspace (``workspace``) or is malformed.

    ``workspace=False`` (an experiment with ``out_of_reach: true``) keeps only the shape and
    finiteness checks.

    Raises:
        UnreachableTrajectory: Naming the first unreachable point and its time, or a trajectory
            whose dimension does not match the robot's task.
    """
    expected = np.shape(robot.forward(robot.configuration(np.zeros(robot.nv))))
    for t in np.linspace(0.0, duration, REACH_SAMPLES):
        x, xdot = trajectory.sample(float(t))
        x, xdot = np.asarray(x, dtype=float), np.asarray(xdot, dtype=float)
        if x.shape != expected:
            raise UnreachableTrajectory(
                field,
                f"gives points of shape {x.shape} but {robot.name} has a {robot.task_kind} task "
                f"of shape {expected}; choose a trajectory of that dimension",
            )
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(xdot))):
            raise UnreachableTrajectory(field, f"is not finite at t = {t:.3g} s")
        if workspace and not robot.can_reach(x):
            point = np.round(task_position(np.asarray(x)), 4).tolist()
            raise UnreachableTrajectory(
                field, f"point {point} at t = {t:.3g} s is outside the workspace of {robot.name}"
            )


@contextlib.contextmanager
def captured_stderr() -> Iterator[None]:
    """Collect what C libraries (urdfdom) write to file descriptor 2; replay it on success.

    On failure it is dropped, so the one-line error is the only thing the user sees.
    """
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
        sink.seek(0)
        text = sink.read()
    if text:
        sys.stderr.write(text.decode("utf-8", "replace"))


def load_robot(config: ExperimentConfig, field: str) -> Robot:
    """Build the robot; numeric warnings (e.g. overflowing link lengths) become a ConfigError.

    Raises:
        ConfigError: Unknown robot, bad parameter, or parameters that overflow.
    """
    try:
        with captured_stderr(), warnings.catch_warnings():
            warnings.simplefilter("error")
            robot: Robot = registry.create(
                registry.ROBOTS, config.robot.type, config.robot.params, field
            )
    except (Warning, ArithmeticError) as error:
        raise ConfigError(field, f"parameters out of range: {_short(error)}") from None
    return robot


def check_robot(robot: Robot, q0: FloatArray, field: str) -> None:
    """Reject robot parameters that make the kinematics non-finite, and NaN limits.

    Raises:
        ConfigError: Naming the robot or ``q0`` field.
    """
    if np.any(np.abs(robot.joint_coordinates(q0)) > MAX_JOINT_COORDINATE):
        raise ConfigError(
            f"{field}.q0", f"every joint coordinate must be within ±{MAX_JOINT_COORDINATE:g}"
        )
    lower, upper = robot.position_limits
    if np.any(np.isnan(lower)) or np.any(np.isnan(upper)):
        raise ConfigError(f"{field}.robot", "position limits must not be NaN")
    speed = np.asarray(robot.velocity_limits, dtype=float)
    if np.any(np.isnan(speed)) or np.any(speed <= 0.0):
        raise ConfigError(f"{field}.robot", "velocity limits must be > 0 (inf: unbounded), not NaN")
    x, jacobian = robot.kinematics(q0)
    scale = float(np.max(np.abs(x[:3]))) if np.size(x) else 0.0
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(jacobian))) or scale > 1.0e6:
        raise ConfigError(
            f"{field}.robot",
            "kinematics at q0 are not finite or beyond 1e6 m; check link lengths and q0",
        )


def check_step_count(steps: float, max_steps: int, values_per_step: int, field: str) -> None:
    """Refuse more than ``max_steps`` control steps per run, saying how much memory it takes.

    Raises:
        ConfigError: On ``duration``/``dt``, with the memory the logs would need.
    """
    if not math.isfinite(steps) or steps > max_steps:
        gib = (
            steps * values_per_step * _BYTES_PER_VALUE / 2**30 if math.isfinite(steps) else math.inf
        )
        raise ConfigError(
            field,
            f"duration/dt = {steps:.3g} steps per run exceeds max_steps = {max_steps} "
            f"(the logs would take about {gib:.3g} GiB per run); shorten duration, raise dt, "
            "or raise max_steps (config key, or --max-steps) explicitly",
        )


def dry_run(controller: Controller, robot: Robot, state: KinematicState, xdot: FloatArray) -> None:
    """Take one step with a copy of ``controller`` at the start configuration.

    Bad per-controller parameters (e.g. a wrong-length ``acceleration_limit``) then fail
    before any compute; the controller itself is left untouched.
    """
    trial = copy.deepcopy(controller)
    trial.bind(robot, 1.0)
    trial.step(state, xdot, np.zeros(robot.nv))


def check_controllers(
    controllers: list[Controller],
    robot: Robot,
    state: KinematicState,
    trajectory: Trajectory,
    field: str,
) -> None:
    """Dry-run every controller at the start (see :func:`dry_run`).

    Raises:
        ConfigError: Naming the controller whose parameters do not fit the robot.
    """
    xdot = np.asarray(trajectory.sample(0.0)[1], dtype=float)
    for j, controller in enumerate(controllers):
        where = f"{field}.controllers.{j} ({controller.name})"
        try:
            dry_run(controller, robot, state, xdot)
        except OtmmError as error:
            if not isinstance(error, DimensionError | ConfigError):
                continue  # a run-time condition (e.g. infeasible), reported by the run itself
            raise ConfigError(where, _short(error)) from None
        except (ValueError, TypeError, IndexError, ArithmeticError) as error:
            raise ConfigError(
                where,
                f"fails on its first step with robot {robot.name} (nv = {robot.nv}, "
                f"task {robot.task_dim}): {_short(error)}",
            ) from None


def prepare_experiment(
    suite: SuiteConfig, index: int, source: str = "config", max_steps: int | None = None
) -> PreparedExperiment:
    """Build and check experiment ``index`` of ``suite``.

    Raises:
        ConfigError: Any bad input, with the config path of the field at fault.
    """
    config = suite.experiments[index]
    field = f"{source}: experiments.{index}"
    max_steps = suite.max_steps if max_steps is None else max_steps
    robot = load_robot(config, f"{field}.robot")
    q0 = _start_configuration(robot, config, field)
    weight = _task_weight(robot, config, field)
    trajectory = _build_trajectory(config, field, robot.forward(q0))
    duration = config.duration if config.duration is not None else trajectory.duration
    dt = config.dt if config.dt is not None else suite.dt
    loop_modes = list(config.loop_modes or suite.loop_modes)
    values = 3 * robot.nv + 4 * robot.task_dim + 12
    duration_field = f"{field}.duration" if config.duration is not None else f"{field}.trajectory"
    if not math.isfinite(duration) or duration <= 0.0:
        raise ConfigError(duration_field, f"duration must be finite and > 0, got {duration:.3g}")
    check_step_count(duration / dt, max_steps, values, duration_field)
    check_robot(robot, q0, field)
    check_reachable(
        robot, trajectory, duration, f"{field}.trajectory", workspace=not config.out_of_reach
    )
    controllers, skipped = _build_controllers(config, field, suite.metrics.blow_up_speed)
    check_controllers(
        controllers, robot, KinematicState.compute(robot, q0, weight), trajectory, field
    )
    return PreparedExperiment(
        config=config,
        robot=robot,
        q0=q0,
        trajectory=trajectory,
        controllers=controllers,
        dt=dt,
        duration=duration,
        loop_modes=loop_modes,
        clik_gain=config.clik_gain if config.clik_gain is not None else suite.clik_gain,
        task_weight=weight,
        skipped=skipped,
    )


def _start_configuration(robot: Robot, config: ExperimentConfig, field: str) -> FloatArray:
    """``config.q0`` as checked by the robot; a ConfigError on ``q0`` gives its reason."""
    try:
        return robot.check_start(np.asarray(config.q0, dtype=float))
    except OtmmError as error:
        message = str(error).removeprefix("q0: ")
        raise ConfigError(f"{field}.q0", message) from error


def _task_weight(robot: Robot, config: ExperimentConfig, field: str) -> FloatArray | None:
    """``config.task_weight`` as an array (ConfigError unless of the task's size), or None."""
    if config.task_weight is None:
        return None
    weight = np.asarray(config.task_weight, dtype=float)
    if weight.shape != (robot.task_dim,):
        raise ConfigError(
            f"{field}.task_weight",
            f"expected shape {(robot.task_dim,)}, got {weight.shape}",
        )
    return weight


def _build_trajectory(config: ExperimentConfig, field: str, x0: FloatArray) -> Trajectory:
    """The experiment's trajectory from the registry, starting at ``x0``, named by its type."""
    trajectory: Trajectory = registry.create(
        registry.TRAJECTORIES,
        config.trajectory.type,
        config.trajectory.params,
        f"{field}.trajectory",
        start=x0,
    )
    trajectory.name = config.trajectory.type
    return trajectory


def _build_controllers(
    config: ExperimentConfig, field: str, divergence_speed: float
) -> tuple[list[Controller], list[SkippedController]]:
    """Build every controller; one whose peer library is missing is skipped, not fatal."""
    controllers: list[Controller] = []
    skipped: list[SkippedController] = []
    for j, spec in enumerate(config.controllers):
        try:
            controllers.append(build_controller(spec, f"{field}.controllers.{j}", divergence_speed))
        except PeerUnavailable as error:
            filters = "+".join(f.type for f in spec.filters) or "none"
            skipped.append(SkippedController(spec.name, filters, spec.backend.type, str(error)))
    return controllers, skipped
