r"""The state sequences a benchmark replays, recorded from real :func:`simulate` runs.

Each scenario runs OTMM + QP (daqp) with CLIK (gain :data:`CLIK_GAIN`, period :data:`DT`)
through :func:`~otmm_qp.simulation.simulate.simulate` — the very loop of ``otmm-qp run`` —
and keeps, through its ``on_step`` observer, the configuration ``q_k``, the commanded task
velocity ``ẋ_c`` and ``q̇_{k-1}`` of evenly spaced steps. Every pipeline then solves exactly
those problems.

* **Panda, 6-D pose** (7 DoF, fingers locked): a pose line from the ready configuration to
  past the edge of the reach along +x (the ``panda_reach`` scenario), which drives σ_min
  toward 0 so the OTMM filter is active near the end.
* **Planar 2-link, 2-D position**: a circle whose far side crosses the stretched singularity.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from otmm_qp import registry
from otmm_qp.controller import Controller, ControllerOutput
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.simulation import Episode, Loop, simulate
from otmm_qp.state import KinematicState
from otmm_qp.trajectories.trajectory import Trajectory

DT = 0.01  # [s]
CLIK_GAIN = 10.0  # [1/s]
#: The OTMM filter of every OTMM pipeline: σ_S = 0.05, linear p, every small σ_i filtered.
OTMM_PARAMS = {"sigma_s": 0.05, "p": "linear", "corank": "all"}


@dataclass
class Scenario:
    """A robot and the replayed sequence of step inputs.

    Attributes:
        name: Table title.
        robot: The arm.
        q: Configurations, shape ``(N, nq)``.
        xdot: Commanded task velocities ``ẋ_c`` (physical units), shape ``(N, n)``.
        qdot_prev: Previous joint velocity of the generating run [rad/s], shape ``(N, nv)``.
        bounded_fraction: Fraction of the recording run's steps with a joint bound active.
        description: One line on the trajectory.
        trajectory: The recording run's desired motion (what a preview backend reads).
        times: Time [s] of each replayed state, shape ``(N,)``.
    """

    name: str
    robot: Robot
    q: FloatArray
    xdot: FloatArray
    qdot_prev: FloatArray
    bounded_fraction: float
    description: str = ""
    trajectory: Trajectory | None = None
    times: FloatArray | None = None

    @property
    def steps(self) -> int:
        """Number of replayed states ``N``."""
        return int(self.q.shape[0])


def otmm_controller(name: str, backend: str, params: dict[str, object]) -> Controller:
    """OTMM (:data:`OTMM_PARAMS`) in front of a registered backend."""
    task_filter = registry.create(registry.FILTERS, "otmm", OTMM_PARAMS, f"{name}.filters.0")
    backend_object = registry.create(registry.BACKENDS, backend, params, f"{name}.backend")
    return Controller(
        name, [task_filter], backend_object, filter_names=["otmm"], backend_name=backend
    )


def record(
    name: str, robot: Robot, trajectory: Trajectory, q0: FloatArray, duration: float, steps: int
) -> Scenario:
    """Run OTMM + QP (daqp) with CLIK for ``duration`` [s]; keep ``steps`` evenly spaced states.

    The run always uses :data:`DT`, so the problems do not depend on ``steps``.
    """
    total = max(1, int(round(duration / DT)))
    picks = set(np.unique(np.linspace(0, total - 1, steps).round().astype(int)).tolist())
    kept: list[tuple[FloatArray, FloatArray, FloatArray]] = []
    times: list[float] = []

    def keep(
        k: int,
        state: KinematicState,
        command: FloatArray,
        qdot_prev: FloatArray,
        _: ControllerOutput,
    ) -> None:
        if k in picks:
            kept.append((state.q.copy(), command.copy(), qdot_prev.copy()))
            times.append(k * DT)

    controller = otmm_controller("otmm+qp", "qp", {"solver": "daqp"})
    observer: Callable[..., None] = keep
    episode = Episode(robot, trajectory, q0, DT, duration, Loop("clik", CLIK_GAIN))
    result = simulate(episode, controller, on_step=observer)
    q, xdot, qdot_prev = (np.array([row[i] for row in kept]) for i in range(3))
    bounded = float(np.mean(result.status == "bounded")) if result.steps else 0.0
    return Scenario(name, robot, q, xdot, qdot_prev, bounded, "", trajectory, np.array(times))


def panda_scenario(steps: int) -> Scenario:
    """Panda pose line toward the edge of its reach (σ_min → 0 near the end)."""
    robot = registry.create(
        registry.ROBOTS, "pinocchio", {"name": "panda", "task": "pose"}, "panda"
    )
    q0 = robot.configuration(np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8]))
    start = robot.forward(q0)
    # The panda_reach pose scenario: a 4 s line, then 1 s held at the unreachable end.
    trajectory = registry.create(
        registry.TRAJECTORIES, "pose_line", {"end": [0.95, 0.0, 0.45], "duration": 4.0},
        "panda.trajectory", start=start,
    )  # fmt: skip
    scenario = record("Panda, 6-D pose task (7 DoF)", robot, trajectory, q0, 5.0, steps)
    scenario.description = (
        f"pose line to (0.95, 0, 0.45) m (past the reach) in 4 s, 5 s run, CLIK "
        f"K = {CLIK_GAIN:g}/s, dt = {DT} s, {scenario.steps} states"
    )
    return scenario


def planar_scenario(steps: int) -> Scenario:
    """Planar 2-link circle whose far side crosses the stretched singularity."""
    robot = registry.create(
        registry.ROBOTS, "planar",
        {"link_lengths": [1.0, 1.0], "limits": [[-3.0, 3.0]] * 2, "velocity_limits": [3.0, 3.0]},
        "planar",
    )  # fmt: skip
    q0 = np.array([0.3, 1.2])
    trajectory = registry.create(
        registry.TRAJECTORIES, "circle", {"centre": [1.2, 0.5], "radius": 0.8, "period": 4.0},
        "planar.trajectory", start=robot.forward(q0),
    )  # fmt: skip
    scenario = record("Planar 2-link, 2-D position task", robot, trajectory, q0, 4.0, steps)
    scenario.description = (
        f"circle centre (1.2, 0.5) m, radius 0.8 m, period 4 s, CLIK, {scenario.steps} states"
    )
    return scenario
