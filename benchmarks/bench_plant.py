"""Per-control-step cost of each plant and conditioning stage on the Panda (timing only).

Records the joint-velocity commands of a real run (Panda pose line past the reach, OTMM + DLS,
CLIK, dt = 10 ms), then replays them through each plant (``measure`` + ``advance``: for
MuJoCo the whole simulated period, 5 substeps of 2 ms, or 10 of 1 ms) and each conditioning
stage (``apply``), the pipelines interleaved round by round so a busy shared machine slows
all alike. Prints median / p90 [µs] per control step.
Run: ``python benchmarks/bench_plant.py [--steps 300] [--rounds 5]``.
"""

from __future__ import annotations

from otmm_qp.blas_threads import prefer_single_threaded_blas

prefer_single_threaded_blas()  # before NumPy loads: one BLAS thread, as the CLI runs

import argparse  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402

import numpy as np  # noqa: E402

from otmm_qp.conditioning import build_conditioning  # noqa: E402
from otmm_qp.controller import Controller  # noqa: E402
from otmm_qp.exceptions import ConfigError  # noqa: E402
from otmm_qp.filters.otmm import OtmmFilter  # noqa: E402
from otmm_qp.plants import build_plant  # noqa: E402
from otmm_qp.robots.pinocchio_arm import PinocchioArm  # noqa: E402
from otmm_qp.simulation.episode import Episode, Loop  # noqa: E402
from otmm_qp.simulation.simulate import simulate  # noqa: E402
from otmm_qp.trajectories.pose import PoseLineTrajectory  # noqa: E402
from otmm_qp_controllers.dls import DampedLeastSquaresBackend  # noqa: E402

DT = 0.01  # [s]

PLANTS: dict[str, object] = {
    "ideal": None,
    "lag": {"type": "lag", "tau": 0.02},
    "delay": {"type": "delay", "steps": 1},
    "sensor": {"type": "sensor", "noise": 1e-4, "counts": 1 << 19},
    "lag+delay+sensor": [
        {"type": "lag", "tau": 0.02},
        {"type": "delay", "steps": 1},
        {"type": "sensor", "noise": 1e-4},
    ],
    "mujoco (2 ms)": {"type": "mujoco", "timestep": 0.002},
    "mujoco (1 ms)": {"type": "mujoco", "timestep": 0.001},
}
STAGES: dict[str, list[dict[str, object]]] = {
    "speed_scale": [{"type": "speed_scale"}],
    "jerk_limit": [{"type": "jerk_limit", "acceleration": 10.0, "jerk": 200.0}],
    "position_clip": [{"type": "position_clip"}],
}


def record(steps: int) -> tuple[PinocchioArm, np.ndarray, np.ndarray]:
    """The arm, its start ``q0`` (nq,) and ``steps`` recorded commands ``q̇`` (N, nv)."""
    robot = PinocchioArm(name="panda", task="pose")
    q0 = robot.configuration(np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8]))
    trajectory = PoseLineTrajectory(robot.forward(q0), end=[0.95, 0.0, 0.45], duration=4.0)
    controller = Controller("r", [OtmmFilter(0.05, corank="all")], DampedLeastSquaresBackend(0.05))
    episode = Episode(robot, trajectory, q0, DT, steps * DT, loop=Loop("clik", 10.0))
    result = simulate(episode, controller)
    return robot, q0, result.qdot[:steps]


def pipelines(robot: PinocchioArm, q0: np.ndarray) -> dict[str, Callable[[np.ndarray], None]]:
    """One step function per pipeline (each keeps its own plant state across calls)."""
    steps: dict[str, Callable[[np.ndarray], None]] = {}
    for name, spec in PLANTS.items():
        plant = build_plant(spec)
        plant.reset(robot, q0, DT)
        state = {"q": q0}

        def step(qdot: np.ndarray, plant=plant, state=state) -> None:  # noqa: ANN001
            plant.measure(state["q"])
            state["q"] = plant.advance(state["q"], qdot).q

        steps[f"plant {name}"] = step
    for name, spec in STAGES.items():
        try:
            stage = build_conditioning(spec)
        except ConfigError as error:  # an optional library (Ruckig) missing: say so, time the rest
            print(f"skipped stage {name}: {error}")
            continue
        stage.reset(robot, DT)
        steps[f"stage {name}"] = lambda qdot, stage=stage: stage.apply(q0, qdot)  # noqa: E731
    return steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    robot, q0, commands = record(args.steps)
    steps = pipelines(robot, q0)
    times: dict[str, list[float]] = {name: [] for name in steps}
    for _ in range(args.rounds):
        for name, step in steps.items():
            for qdot in commands:
                tic = time.perf_counter()
                step(qdot)
                times[name].append(time.perf_counter() - tic)
    width = max(len(n) for n in steps)
    print(f"{'pipeline':<{width}}  median µs   p90 µs  ({len(commands)} steps × {args.rounds})")
    for name, samples in times.items():
        micro = np.array(samples) * 1e6
        print(f"{name:<{width}}  {np.median(micro):9.1f} {np.percentile(micro, 90):8.1f}")


if __name__ == "__main__":
    main()
