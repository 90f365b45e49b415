r"""Per-step cost of otmm-qp pipelines against pink, mink and Drake, measured side by side.

One process times every pipeline on the *same* sequence of states. The states come from a
closed-loop (CLIK, gain :data:`CLIK_GAIN`) run of OTMM + QP along a trajectory; every
pipeline then replays them, so all solve the same problems:

* **Panda, 6-D pose** (7 DoF, fingers locked): a pose line from the ready configuration to
  the edge of the reach along +x (the end of the ``panda_reach`` scenario), which drives
  σ_min toward 0 so the OTMM filter is active near the end.
* **Planar 2-link, 2-D position**: a circle whose far side crosses the stretched singularity.

What one *control step* is, per library (everything from the configuration to ``q̇``):

* otmm-qp: ``KinematicState.compute(robot, q)`` (Pinocchio kinematics + the one SVD) and
  ``Controller.step(state, ẋ, q̇_prev)`` (filters + backend);
* pink: ``Configuration.update(q)`` + ``FrameTask.set_target(T*)`` + ``solve_ik``;
* mink: ``Configuration.update(q)`` + ``FrameTask.set_target(T*)`` + ``solve_ik``;
* Drake: ``SetPositions`` + ``DoDifferentialInverseKinematics`` (via
  :class:`~otmm_qp.peers.drake_backend.DrakeBackend`).

The peers are configured as in :mod:`otmm_qp.peers` (same Pinocchio model / URDF, joint
position and velocity limits, Tikhonov damping 1e-12); their target ``T*`` is the pose
reached after ``dt`` at the commanded twist (precomputed, as a trajectory would supply it).
QP solvers get the same options through pink/mink as through otmm-qp
(:data:`~otmm_qp_controllers.qp_problem.SOLVER_OPTIONS`). Pipelines are interleaved: each
round runs every pipeline over the whole sequence, in a new random order.
"""

from __future__ import annotations

import contextlib
import importlib.metadata
import json
import os
import platform
import sys
import time
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from qpsolvers.warnings import SparseConversionWarning

from otmm_qp.controller import Controller
from otmm_qp.exceptions import ConfigError, PeerUnavailable
from otmm_qp.filters.otmm import OtmmFilter
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.simulation.loop_modes import commanded_velocity
from otmm_qp.simulation.simulate import simulate
from otmm_qp.state import KinematicState
from otmm_qp.trajectories.circle import CircleTrajectory
from otmm_qp.trajectories.pose import PoseLineTrajectory
from otmm_qp.trajectories.trajectory import Trajectory
from otmm_qp_controllers.dls import DampedLeastSquaresBackend
from otmm_qp_controllers.dls_adaptive import AdaptiveDampedLeastSquaresBackend
from otmm_qp_controllers.pinv import PseudoInverseBackend
from otmm_qp_controllers.qp import QpBackend
from otmm_qp_controllers.qp_problem import SOLVER_OPTIONS

DT = 0.01  # [s]
CLIK_GAIN = 10.0  # [1/s]
ROUNDS = 5
#: Peer QP solvers timed through pink and mink (and the matching otmm-qp solvers).
PEER_SOLVERS = ("daqp", "proxqp", "osqp")
#: otmm-qp QP solver → the pink pipeline it is compared with.
SAME_SOLVER = {
    "daqp": "daqp",
    "direct_daqp": "daqp",
    "proxqp": "proxqp",
    "direct_proxsuite": "proxqp",
    "osqp": "osqp",
    "direct_osqp": "osqp",
}
REFERENCE = "pink (daqp)"
LIBRARIES = (
    "numpy", "scipy", "pin", "qpsolvers", "daqp", "proxsuite", "osqp", "pin-pink", "mink",
    "mujoco", "drake",
)  # fmt: skip

StepFunction = Callable[[int], None]


@dataclass
class Scenario:
    """A robot and the replayed sequence of states.

    Attributes:
        name: Table title.
        robot: The arm.
        q: Configurations, shape ``(N, nq)``.
        xdot: Commanded task velocities ``ẋ_c`` (physical units), shape ``(N, n)``.
        qdot_prev: Previous joint velocity of the generating run [rad/s], shape ``(N, nv)``.
        description: One line on the trajectory.
    """

    name: str
    robot: Robot
    q: FloatArray
    xdot: FloatArray
    qdot_prev: FloatArray
    description: str


def _otmm() -> OtmmFilter:
    return OtmmFilter(0.05, p="linear", corank="all")


def _record(
    robot: Robot, trajectory: Trajectory, q0: FloatArray, duration: float, steps: int
) -> Scenario:
    """Run OTMM + QP (daqp) with CLIK for ``duration`` [s]; keep ``steps`` evenly spaced states.

    The run itself always uses :data:`DT`, so the problems do not depend on ``steps``.
    """
    controller = Controller("otmm+qp", [_otmm()], QpBackend(solver="direct_daqp"))
    result = simulate(robot, controller, trajectory, q0, DT, duration, "clik", CLIK_GAIN)
    picks = np.unique(np.linspace(0, len(result.t) - 1, steps).round().astype(int))
    qs = np.array([robot.configuration(result.q[k]) for k in picks])
    xdots = np.empty((picks.size, robot.task_dim))
    for i, k in enumerate(picks):
        tk = float(result.t[k])
        x, _ = robot.kinematics(qs[i])
        xd, xd_dot = trajectory.sample(tk)
        xdots[i] = commanded_velocity("clik", robot, trajectory, tk, DT, x, xd, xd_dot, CLIK_GAIN)
    prev = np.vstack([np.zeros((1, robot.nv)), result.qdot[:-1]])[picks]
    return Scenario("", robot, qs, xdots, prev, "")


def panda_scenario(steps: int) -> Scenario:
    """Panda pose line toward the edge of its reach (σ_min → 0 near the end)."""
    robot = PinocchioArm(name="panda", task="pose")
    q0 = robot.configuration(np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8]))
    start, _ = robot.kinematics(q0)
    # The panda_reach pose scenario: a 4 s line, then 1 s held at the unreachable end.
    trajectory = PoseLineTrajectory(np.array(start), end=[0.95, 0.0, 0.45], duration=4.0)
    scenario = _record(robot, trajectory, q0, 5.0, steps)
    scenario.name = "Panda, 6-D pose task (7 DoF)"
    scenario.description = (
        f"pose line to (0.95, 0, 0.45) m (past the reach) in 4 s, 5 s run, CLIK "
        f"K = {CLIK_GAIN:g}/s, dt = {DT} s, {len(scenario.q)} states"
    )
    return scenario


def planar_scenario(steps: int) -> Scenario:
    """Planar 2-link circle whose far side crosses the stretched singularity."""
    robot = PlanarArm([1.0, 1.0], limits=[[-3.0, 3.0]] * 2, velocity_limits=[3.0, 3.0])
    q0 = np.array([0.3, 1.2])
    start = robot.kinematics(q0)[0]
    trajectory = CircleTrajectory(start, centre=[1.2, 0.5], radius=0.8, period=4.0)
    scenario = _record(robot, trajectory, q0, 4.0, steps)
    scenario.name = "Planar 2-link, 2-D position task"
    scenario.description = (
        f"circle centre (1.2, 0.5) m, radius 0.8 m, period 4 s, CLIK, {len(scenario.q)} states"
    )
    return scenario


# ---------------------------------------------------------------------------- pipelines
def otmm_pipelines(full: bool) -> dict[str, Controller]:
    """otmm-qp controllers: each backend alone and with OTMM in front."""
    backends: dict[str, Callable[[], Any]] = {
        "pinv": PseudoInverseBackend,
        "dls": lambda: DampedLeastSquaresBackend(damping=0.05),
        "dls_adaptive": lambda: AdaptiveDampedLeastSquaresBackend(
            alpha=0.003, sigma_threshold=0.05
        ),
    }
    solvers = list(SAME_SOLVER) if full else ["daqp", "direct_daqp"]
    for solver in solvers:
        backends[f"qp ({solver})"] = partial(QpBackend, solver=solver)
    pipelines: dict[str, Controller] = {}
    for name, make in backends.items():
        pipelines[name] = Controller(name, [], make())
        pipelines[f"otmm+{name}"] = Controller(f"otmm+{name}", [_otmm()], make())
    for solver in solvers:  # the QP on every step: the cost when bounds are active
        name = f"otmm+qp ({solver}, QP every step)"
        pipelines[name] = Controller(name, [_otmm()], QpBackend(solver=solver, fast_path=False))
    return pipelines


def _otmm_step(scenario: Scenario, controller: Controller) -> StepFunction:
    robot, qs, xdots, prevs = scenario.robot, scenario.q, scenario.xdot, scenario.qdot_prev
    controller.bind(robot, DT)
    compute, step = KinematicState.compute, controller.step

    def run(k: int) -> None:
        step(compute(robot, qs[k]), xdots[k], prevs[k])

    return run


def _targets(scenario: Scenario, pose_of: Callable[[int], FloatArray]) -> list[FloatArray]:
    from otmm_qp.peers.peer_backend import PeerBackend

    targets = []
    for k in range(len(scenario.q)):
        linear, angular = PeerBackend.spatial_velocity(scenario.robot, scenario.xdot[k])
        targets.append(PeerBackend.advanced_pose(pose_of(k), linear, angular, DT))
    return targets


def _pink_step(scenario: Scenario, solver: str) -> StepFunction:
    import pink
    import pinocchio as pin
    from pink.exceptions import PinkError

    from otmm_qp.peers.pink_backend import PinkBackend

    adapter = PinkBackend(solver=solver)  # its bind builds model, task and limits
    adapter.bind(scenario.robot, DT)
    configuration, task, limits = adapter._configuration, adapter._task, adapter._limits
    frame = adapter._frame
    qs = [adapter._pin_configuration(q) for q in scenario.q]

    def pose(k: int) -> FloatArray:
        configuration.update(qs[k])
        return np.asarray(configuration.get_transform_frame_to_world(frame).homogeneous)

    targets = [pin.SE3(t) for t in _targets(scenario, pose)]
    options = SOLVER_OPTIONS.get(solver, {})
    solve_ik = pink.solve_ik

    def run(k: int) -> None:
        configuration.update(qs[k])
        task.set_target(targets[k])
        try:
            solve_ik(
                configuration, [task], DT, solver=solver, damping=1e-12, limits=limits,
                safety_break=False, **options,
            )  # fmt: skip
        except PinkError:  # counted as a step, as the pink adapter does (q̇ = 0)
            pass

    return run


def _mink_step(scenario: Scenario, solver: str) -> StepFunction:
    import mink

    from otmm_qp.peers.mink_backend import MinkBackend

    adapter = MinkBackend(solver=solver)
    adapter.bind(scenario.robot, DT)
    configuration, task, limits = adapter._configuration, adapter._task, adapter._limits
    site, robot = adapter._site, scenario.robot
    qs = [adapter._map.to_peer(robot.joint_coordinates(q), adapter._qpos0) for q in scenario.q]

    def pose(k: int) -> FloatArray:
        configuration.update(qs[k])
        return np.asarray(configuration.get_transform_frame_to_world(site, "site").as_matrix())

    targets = [mink.SE3.from_matrix(t) for t in _targets(scenario, pose)]
    options = SOLVER_OPTIONS.get(solver, {})
    solve_ik = mink.solve_ik

    def run(k: int) -> None:
        configuration.update(qs[k])
        task.set_target(targets[k])
        try:
            solve_ik(configuration, [task], DT, solver, damping=1e-12, limits=limits, **options)
        except mink.MinkError:  # counted as a step, as the mink adapter does (q̇ = 0)
            pass

    return run


def _drake_step(scenario: Scenario) -> StepFunction:
    from otmm_qp.peers.drake_backend import DrakeBackend

    adapter = DrakeBackend()
    adapter.bind(scenario.robot, DT)
    robot = scenario.robot
    states = [KinematicState.compute(robot, q) for q in scenario.q]  # Drake reads only q
    xdots, prevs, solve = scenario.xdot, scenario.qdot_prev, adapter.solve

    def run(k: int) -> None:
        solve(states[k], xdots[k], prevs[k])

    return run


def peer_pipelines(scenario: Scenario, full: bool) -> tuple[dict[str, StepFunction], list[str]]:
    """Step functions of the installed peers, and notes on the missing ones."""
    steps: dict[str, StepFunction] = {}
    notes: list[str] = []
    solvers = PEER_SOLVERS if full else ("daqp",)
    makers: list[tuple[str, Callable[[], StepFunction]]] = []
    for solver in solvers:
        makers.append((f"pink ({solver})", partial(_pink_step, scenario, solver)))
    for solver in solvers:
        makers.append((f"mink ({solver})", partial(_mink_step, scenario, solver)))
    makers.append(("drake (DiffIK)", partial(_drake_step, scenario)))
    for name, make in makers:
        try:
            with _quiet_logs():
                steps[name] = make()
        except (PeerUnavailable, ConfigError, ImportError) as error:
            notes.append(f"{name}: skipped ({error})")
    return steps, notes


# ---------------------------------------------------------------------------- timing
@contextlib.contextmanager
def _quiet_stdout() -> Iterator[None]:
    """Send file descriptor 1 to /dev/null (OSQP's C code prints from inside solves)."""
    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)
        os.close(devnull)


@contextlib.contextmanager
def _quiet_logs() -> Iterator[None]:
    """Silence Drake's URDF parser warnings while the peers are built."""
    import logging

    logger = logging.getLogger("drake")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


def time_pipelines(
    pipelines: dict[str, StepFunction], steps: int, rounds: int, seed: int = 0
) -> dict[str, FloatArray]:
    """Per-step times [µs] of each pipeline, shape ``(rounds·steps,)``, rounds interleaved.

    Each round runs every pipeline once over the whole state sequence (as a control loop
    would, keeping caches and warm starts), in a fresh random order. One untimed pass per
    pipeline precedes round 0 (imports, first solver set-up).
    """
    rng = np.random.default_rng(seed)
    names = list(pipelines)
    samples = {name: np.empty((rounds, steps)) for name in names}
    clock = time.perf_counter
    with _quiet_stdout():
        for run in pipelines.values():  # warm-up pass: imports, first solver set-up
            for k in range(steps):
                run(k)
        for r in range(rounds):
            for name in rng.permutation(names):
                run, row = pipelines[name], samples[name][r]
                for k in range(steps):
                    start = clock()
                    run(k)
                    row[k] = clock() - start
    return {name: samples[name].ravel() * 1e6 for name in names}


def summarise(times: dict[str, FloatArray]) -> list[dict[str, Any]]:
    """Median, p10, p90, p99 [µs] and the ratio of medians to :data:`REFERENCE`."""
    reference = float(np.median(times[REFERENCE])) if REFERENCE in times else float("nan")
    rows = []
    for name, t in times.items():
        median = float(np.median(t))
        p10, p90, p99 = (float(v) for v in np.percentile(t, [10, 90, 99]))
        rows.append(
            {
                "pipeline": name,
                "library": name.split(" ")[0] if name.split(" ")[0] in PEERS else "otmm-qp",
                "median_us": median,
                "p10_us": p10,
                "p90_us": p90,
                "p99_us": p99,
                "ratio_to_pink_daqp": median / reference,
            }
        )
    return rows


PEERS = ("pink", "mink", "drake")


def check_targets(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The issue's three targets, evaluated on medians of the same run."""
    median = {row["pipeline"]: row["median_us"] for row in rows}
    reference = median.get(REFERENCE)
    checks: list[dict[str, Any]] = []
    if reference is None:
        return checks
    for name, value in median.items():
        if name.startswith("otmm+qp (") and "every step" not in name:
            checks.append(_check(f"{name} ≤ 0.5 × {REFERENCE}", value, 0.5 * reference))
    if "otmm+pinv" in median:
        checks.append(_check(f"otmm+pinv ≤ 0.35 × {REFERENCE}", median["otmm+pinv"],
                             0.35 * reference))  # fmt: skip
    for name, value in median.items():
        if "qp (" not in name or name.split(" ")[0] in PEERS:
            continue
        solver = name.split("(")[1].split(",")[0].rstrip(")")
        peer = f"pink ({SAME_SOLVER[solver]})"
        if peer in median:
            checks.append(_check(f"{name} ≤ {peer}", value, median[peer]))
    return checks


def _check(label: str, value: float, limit: float) -> dict[str, Any]:
    return {"target": label, "value_us": value, "limit_us": limit, "met": value <= limit}


def machine() -> dict[str, Any]:
    """CPU, core count, load average, Python and library versions."""
    cpu = platform.processor() or platform.machine()
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    versions: dict[str, str | None] = {}
    for library in LIBRARIES:
        try:
            versions[library] = importlib.metadata.version(library)
        except importlib.metadata.PackageNotFoundError:
            versions[library] = None
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "load_average_1_5_15": [round(v, 2) for v in load],
        "platform": platform.platform(),
        "python": platform.python_version(),
        "versions": versions,
    }


# ---------------------------------------------------------------------------- output
def markdown(result: dict[str, Any]) -> str:
    """The Markdown tables of a :func:`run_bench` result."""
    info = result["machine"]
    versions = ", ".join(f"{k} {v}" for k, v in info["versions"].items() if v)
    lines = [
        f"Command: `{result['command']}`  ",
        f"Machine: {info['cpu']}, {info['cores']} cores, load average "
        f"{' / '.join(str(v) for v in info['load_average_1_5_15'])} (1/5/15 min) at the start, "
        f"Python {info['python']}  ",
        f"Libraries: {versions}  ",
        f"One step: {result['step_definition']}  ",
        f"Samples: {result['rounds']} interleaved rounds × the state sequence per pipeline.",
        "",
    ]
    for scenario in result["scenarios"]:
        lines += [
            f"### {scenario['name']}",
            "",
            f"{scenario['description']}; QP called on {scenario['qp_fraction']:.0%} of the "
            "steps by otmm+qp (fast path otherwise).",
            "",
            "| pipeline | median µs | p10 µs | p90 µs | p99 µs | × pink (daqp) |",
            "|---|---:|---:|---:|---:|---:|",
        ]
        for row in sorted(scenario["rows"], key=lambda r: r["median_us"]):
            lines.append(
                f"| {row['pipeline']} | {row['median_us']:.1f} | {row['p10_us']:.1f} | "
                f"{row['p90_us']:.1f} | {row['p99_us']:.1f} | {row['ratio_to_pink_daqp']:.2f} |"
            )
        if scenario["targets"]:
            lines += [
                "",
                "| target (medians, same run) | µs | limit µs | met |",
                "|---|---:|---:|---|",
            ]
            for check in scenario["targets"]:
                lines.append(
                    f"| {check['target']} | {check['value_us']:.1f} | {check['limit_us']:.1f} | "
                    f"{'yes' if check['met'] else '**no**'} |"
                )
        for note in scenario["notes"]:
            lines.append(f"\n_{note}_")
        lines.append("")
    return "\n".join(lines)


STEP_DEFINITION = (
    "otmm-qp: KinematicState.compute (Pinocchio FK + Jacobian + SVD) + Controller.step; "
    "pink / mink: Configuration.update + FrameTask.set_target + solve_ik; "
    "Drake: SetPositions + DoDifferentialInverseKinematics."
)


def _qp_fraction(scenario: Scenario) -> float:
    backend = QpBackend(solver="direct_daqp")
    controller = Controller("probe", [_otmm()], backend)
    controller.bind(scenario.robot, DT)
    used = 0
    for k in range(len(scenario.q)):
        state = KinematicState.compute(scenario.robot, scenario.q[k])
        controller.step(state, scenario.xdot[k], scenario.qdot_prev[k])
        used += backend.used_qp
    return used / len(scenario.q)


def bench_scenario(scenario: Scenario, full: bool, rounds: int) -> dict[str, Any]:
    """Time every pipeline on ``scenario``; rows, targets and notes."""
    steps: dict[str, StepFunction] = {
        name: _otmm_step(scenario, controller) for name, controller in otmm_pipelines(full).items()
    }
    peers, notes = peer_pipelines(scenario, full)
    steps.update(peers)
    times = time_pipelines(steps, len(scenario.q), rounds)
    rows = summarise(times)
    return {
        "name": scenario.name,
        "description": scenario.description,
        "qp_fraction": _qp_fraction(scenario),
        "rows": rows,
        "targets": check_targets(rows),
        "notes": notes,
    }


def run_bench(out_dir: Path, steps: int, rounds: int = ROUNDS) -> int:
    """Time all pipelines, write ``bench.json`` and ``bench.md`` into ``out_dir``, print the table.

    Args:
        out_dir: Output directory (created).
        steps: Length of each replayed state sequence (control steps per pass).
        rounds: Interleaved timing rounds.

    Returns:
        0 (the exit status; unmet targets are reported in the table, not as a failure).
    """
    if steps < 10:
        raise ConfigError("steps", f"must be >= 10, got {steps}")
    info = machine()
    with warnings.catch_warnings():
        # qpsolvers warns on every dense-to-sparse conversion for OSQP (pink's path too):
        # the cost is part of what is measured, the repeated text is not useful.
        warnings.simplefilter("ignore", SparseConversionWarning)
        scenarios = [
            bench_scenario(panda_scenario(steps), True, rounds),
            bench_scenario(planar_scenario(steps), False, rounds),
        ]
    result = {
        "command": f"otmm-qp bench --out {out_dir} --steps {steps}",
        "step_definition": STEP_DEFINITION,
        "rounds": rounds,
        "steps": steps,
        "machine": info,
        "load_average_end": [round(v, 2) for v in os.getloadavg()],
        "scenarios": scenarios,
    }
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "bench.json").write_text(json.dumps(result, indent=2) + "\n")
    table = markdown(result)
    (out_dir / "bench.md").write_text(table + "\n")
    print(table)
    return 0
