"""Turn validated config records into robots, trajectories and controllers."""

from __future__ import annotations

import contextlib
import copy
import os
import sys
import tempfile
import warnings
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from otmm_qp import registry
from otmm_qp.config.schema import ControllerConfig, ExperimentConfig, PluginConfig
from otmm_qp.controller import Controller
from otmm_qp.exceptions import (
    ConfigError,
    DimensionError,
    OtmmError,
    PeerUnavailable,
    PluginNotFound,
    UnreachableTrajectory,
)
from otmm_qp.plants.declaration import PlantDeclaration
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.simulation.episode import Episode
from otmm_qp.simulation.recorder import task_position
from otmm_qp.state import KinematicState
from otmm_qp.status import DIVERGENCE_SPEED
from otmm_qp.trajectories.trajectory import Trajectory

#: Trajectory samples checked against the workspace before running.
REACH_SAMPLES = 200
#: Largest |joint coordinate| accepted in ``q0`` [rad or m]: beyond it trigonometry is noise.
MAX_JOINT_COORDINATE = 1.0e4


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


def build_controller(
    config: ControllerConfig, field: str, divergence_speed: float = DIVERGENCE_SPEED
) -> Controller:
    """Instantiate the filters and backend of a controller record.

    ``divergence_speed`` [rad/s] is the experiment's ``metrics.blow_up_speed``, so a step is
    reported ``diverging`` exactly where the ``blow_up`` metric counts it.

    Raises:
        ConfigError: Unknown plugin name or parameter, or a value out of range.
    """
    filters = [
        registry.create(registry.FILTERS, spec.type, spec.params, f"{field}.filters.{j}")
        for j, spec in enumerate(config.filters)
    ]
    backend = registry.create(
        registry.BACKENDS, config.backend.type, config.backend.params, f"{field}.backend"
    )
    return Controller(
        config.name,
        filters,
        backend,
        divergence_speed,
        filter_names=[spec.type for spec in config.filters],
        backend_name=config.backend.type,
    )


def check_reachable(robot: Robot, trajectory: Trajectory, duration: float, field: str) -> None:
    """Reject a trajectory that leaves the arm's workspace.

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
        if not robot.can_reach(x):
            point = np.round(task_position(np.asarray(x)), 4).tolist()
            reach = getattr(robot, "reach", getattr(robot, "reach_max", None))
            within = f" (reach {float(reach):.3g} m)" if isinstance(reach, float | int) else ""
            raise UnreachableTrajectory(
                field,
                f"point {point} at t = {t:.3g} s is outside the workspace of {robot.name}"
                f"{within}; to run a motion past the reach on purpose, set out_of_reach: true "
                "on the experiment",
            )


@contextlib.contextmanager
def captured_stderr() -> Iterator[None]:
    """Collect what C libraries (urdfdom) write to file descriptor 2; replay it on success.

    On failure it is not printed: the error's first line is the first thing the user sees, and
    an :class:`~otmm_qp.exceptions.OtmmError` without details gets urdfdom's ``Error:`` lines
    as its details (``joint [j1]: limit has no velocity``), printed after it.
    """
    sys.stderr.flush()
    saved = os.dup(2)
    failed: OtmmError | None = None
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield
        except OtmmError as error:
            failed = error
            raise
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            text = sink.read()
            if failed is not None and not failed.details:
                failed.details = parser_errors(text.decode("utf-8", "replace"))
    if text:
        sys.stderr.write(text.decode("utf-8", "replace"))


#: Most parser lines kept as an error's details.
MAX_PARSER_LINES = 5


def parser_errors(text: str) -> tuple[str, ...]:
    """The ``Error:`` lines urdfdom wrote in ``text`` (its ``at line N in FILE`` lines dropped)."""
    found = [
        "urdfdom: " + " ".join(line.split()[1:])
        for line in text.splitlines()
        if line.startswith("Error:") and line.split()[1:]
    ]
    return tuple(found[:MAX_PARSER_LINES])


def load_robot(spec: PluginConfig, field: str) -> Robot:
    """Build a robot block; numeric warnings (e.g. overflowing link lengths) become a ConfigError.

    What C libraries (urdfdom) print while loading is held back when loading fails.

    Raises:
        ConfigError: Unknown robot, bad parameter, or parameters that overflow.
    """
    try:
        with captured_stderr(), warnings.catch_warnings():
            warnings.simplefilter("error")
            robot: Robot = registry.create(registry.ROBOTS, spec.type, spec.params, field)
    except (Warning, ArithmeticError) as error:
        raise ConfigError(field, f"parameters out of range: {_short(error)}") from None
    return robot


def check_robot(robot: Robot, q0: FloatArray, field: str) -> None:
    """Reject robot parameters that make the kinematics non-finite, and NaN limits.

    Raises:
        ConfigError: Naming the robot or ``q0`` field.
    """
    check_coordinates(robot, q0, field)
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


def check_coordinates(robot: Robot, q0: FloatArray, field: str) -> None:
    """Refuse a ``q0`` with a joint coordinate beyond :data:`MAX_JOINT_COORDINATE`.

    Checked before any kinematics: ``q0: [1e308, 1e308]`` overflowed the planar arm's
    forward kinematics (six RuntimeWarning lines before the error line).

    Raises:
        ConfigError: Naming the ``q0`` field.
    """
    if np.any(np.abs(robot.joint_coordinates(q0)) > MAX_JOINT_COORDINATE):
        raise ConfigError(
            f"{field}.q0", f"every joint coordinate must be within ±{MAX_JOINT_COORDINATE:g}"
        )


def start_configuration(robot: Robot, config: ExperimentConfig, field: str) -> FloatArray:
    """``config.q0`` as checked by the robot; a ConfigError on ``q0`` gives its reason."""
    try:
        q0 = robot.check_start(np.asarray(config.q0, dtype=float))
    except OtmmError as error:
        message = str(error).removeprefix("q0: ")
        raise ConfigError(f"{field}.q0", message) from error
    check_coordinates(robot, q0, field)  # before the trajectory reads the pose at q0
    return q0


def build_trajectory(
    config: ExperimentConfig,
    field: str,
    x0: FloatArray,
    robot: Robot | None = None,
    q0: FloatArray | None = None,
) -> Trajectory:
    """The experiment's trajectory from the registry, starting at ``x0 = f(q0)``.

    ``robot`` and ``q0`` are passed to a trajectory that lists them in its
    ``framework_parameters`` (e.g. ``joint_waypoints``).
    """
    field = f"{field}.trajectory"
    try:
        factory = registry.load(registry.TRAJECTORIES, config.trajectory.type)
    except PluginNotFound as error:
        raise ConfigError(field, str(error)) from error
    wanted = getattr(factory, "framework_parameters", ("start",))
    given = {"start": x0, "robot": robot, "q0": q0}
    framework = {name: value for name, value in given.items() if name in wanted}
    trajectory: Trajectory = registry.create(
        registry.TRAJECTORIES, config.trajectory.type, config.trajectory.params, field, **framework
    )
    return trajectory


def build_controllers(
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


def dry_run(
    controller: Controller, episode: Episode, declaration: PlantDeclaration | None = None
) -> None:
    """Take one step with a copy of ``controller`` at the episode's start configuration.

    Bad per-controller parameters (e.g. a wrong-length ``acceleration_limit``, a preview
    horizon the trajectory cannot give or knots that do not fit ``dt``, a ``command`` limit
    reading thresholds its plant does not declare) then fail before any compute; the copy is
    bound with the episode's ``dt``, trajectory and the plant's ``declaration`` (None: none
    handed over), the controller itself is left untouched.
    """
    robot = episode.robot
    state = KinematicState.compute(robot, episode.q0, episode.task_weight)
    xdot = np.asarray(episode.trajectory.sample(0.0)[1], dtype=float)
    trial = copy.deepcopy(controller)
    if declaration is not None:
        trial.declare_plant(declaration)
    trial.bind(robot, episode.dt, episode.trajectory)
    trial.step(state, xdot, np.zeros(robot.nv))


def check_controllers(
    controllers: list[Controller],
    episode: Episode,
    field: str,
    declarations: Mapping[str, Sequence[PlantDeclaration]] | None = None,
) -> None:
    """Dry-run every controller at the episode's start (see :func:`dry_run`).

    Once per plant declaration it will run under (``declarations`` by controller name; none:
    one dry run without).

    A controller whose parameters do not fit the robot fails here. Any other exception (a
    run-time condition such as an infeasible QP, or a plugin failing for its own reasons) is
    left to the run, which records it as that run's failure.

    Raises:
        ConfigError: Naming the controller whose parameters do not fit the robot.
    """
    robot = episode.robot
    for j, controller in enumerate(controllers):
        where = f"{field}.controllers.{j} ({controller.name})"
        try:
            for declaration in (declarations or {}).get(controller.name) or (None,):
                dry_run(controller, episode, declaration)
        except (DimensionError, ConfigError) as error:
            raise ConfigError(where, _short(error)) from None
        except OtmmError:
            continue  # a run-time condition (e.g. infeasible), reported by the run itself
        except (ValueError, TypeError, IndexError, ArithmeticError) as error:
            raise ConfigError(
                where,
                f"fails on its first step with robot {robot.name} (nv = {robot.nv}, "
                f"task {robot.task_dim}): {_short(error)}",
            ) from None
        except (Exception, SystemExit):  # untrusted plugin code: the run records it
            continue
