"""Per-step cost of the issue-11 and issue-20 strategies on Panda (pure timing, no assertions).

Replays Panda states of the panda_reach pose scenario (6-D pose line past the reach, recorded
with OTMM + DLS and CLIK, σ_min down to ~1e-5) through each pipeline, interleaved round by
round so a
busy shared machine slows all alike, and prints median / p90 [µs], the ratio to
OTMM (paper form, cbrt) + pinv and the added µs. Run: ``python benchmarks/bench_strategies.py``.
"""

from __future__ import annotations

from otmm_qp.blas_threads import prefer_single_threaded_blas

prefer_single_threaded_blas()  # before NumPy loads: one BLAS thread, as the CLI runs

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from otmm_qp.controller import Controller  # noqa: E402
from otmm_qp.filters.direction_aware_otmm import DirectionAwareOtmmFilter  # noqa: E402
from otmm_qp.filters.otmm import OtmmFilter  # noqa: E402
from otmm_qp.robots.pinocchio_arm import PinocchioArm  # noqa: E402
from otmm_qp.simulation import Episode, Loop, simulate  # noqa: E402
from otmm_qp.simulation.loop_modes import commanded_velocity  # noqa: E402
from otmm_qp.state import KinematicState  # noqa: E402
from otmm_qp.trajectories.pose import PoseLineTrajectory  # noqa: E402
from otmm_qp_controllers.dls import DampedLeastSquaresBackend  # noqa: E402
from otmm_qp_controllers.dls_error import ErrorDampedLeastSquaresBackend  # noqa: E402
from otmm_qp_controllers.jparse import JParseBackend  # noqa: E402
from otmm_qp_controllers.manipulability import ManipulabilityBackend  # noqa: E402
from otmm_qp_controllers.pinv import PseudoInverseBackend  # noqa: E402
from otmm_qp_controllers.qp import QpBackend  # noqa: E402
from otmm_qp_controllers.qp.manipulability import ManipulabilityQpBackend  # noqa: E402
from otmm_qp_controllers.sigma_lm import SigmaLevenbergMarquardtBackend  # noqa: E402
from otmm_qp_controllers.sns import SnsBackend  # noqa: E402
from otmm_qp_controllers.task_priority import TaskPriorityBackend  # noqa: E402
from otmm_qp_controllers.wln import WeightedLeastNormBackend  # noqa: E402

REFERENCE = "otmm+pinv"
DT = 0.01  # [s]
GAIN = 10.0  # [1/s]


def record(steps: int) -> tuple[PinocchioArm, np.ndarray, np.ndarray, np.ndarray]:
    """States ``q`` (N, nq), commands ``ẋ_c`` (N, 6) and previous ``q̇`` (N, nv)."""
    robot = PinocchioArm(name="panda", task="pose")
    q0 = robot.configuration(np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8]))
    trajectory = PoseLineTrajectory(robot.forward(q0), end=[0.95, 0.0, 0.45], duration=4.0)
    controller = Controller("r", [OtmmFilter(0.05, corank="all")], DampedLeastSquaresBackend(0.05))
    result = simulate(Episode(robot, trajectory, q0, DT, 5.0, Loop("clik", GAIN)), controller)
    picks = np.unique(np.linspace(0, len(result.t) - 1, steps).round().astype(int))
    qs = np.array([robot.configuration(result.q[k]) for k in picks])
    xdots = np.empty((picks.size, 6))
    for i, k in enumerate(picks):
        t = float(result.t[k])
        x = robot.forward(qs[i])
        xd, xd_dot = trajectory.sample(t)
        error = robot.task_error(xd, x)
        xdots[i] = commanded_velocity("clik", robot, trajectory, t, DT, x, error, xd_dot, GAIN)
    previous = np.vstack([np.zeros((1, robot.nv)), result.qdot[:-1]])[picks]
    return robot, qs, xdots, previous


def pipelines() -> dict[str, Controller]:
    return {
        "pinv": Controller("pinv", [], PseudoInverseBackend()),
        REFERENCE: Controller(REFERENCE, [OtmmFilter(0.05, p="cbrt")], PseudoInverseBackend()),
        "otmm-bounded+pinv": Controller(
            "b", [OtmmFilter(0.05, p="bounded")], PseudoInverseBackend()
        ),
        "otmm-directional+pinv": Controller(
            "d", [DirectionAwareOtmmFilter(0.05)], PseudoInverseBackend()
        ),
        "jparse": Controller("j", [], JParseBackend()),
        "sns": Controller("s", [], SnsBackend()),
        "manipulability": Controller("m", [], ManipulabilityBackend(damping=0.05)),
        # issue 20
        "dls_error": Controller("e", [], ErrorDampedLeastSquaresBackend()),
        "task_priority": Controller("t", [], TaskPriorityBackend()),
        "wln": Controller("w", [], WeightedLeastNormBackend(damping=0.05)),
        "jparse-authors": Controller(
            "ja",
            [],
            JParseBackend(
                position_gain=1.0,
                orientation_gain=1.0,
                secondary={"type": "posture", "gain": 3.0, "max_speed": 0.6},
            ),
        ),
        "qp": Controller("q", [], QpBackend()),
        "qp_manipulability": Controller(
            "qm", [], ManipulabilityQpBackend(manipulability_weight=1e-4)
        ),
        "sigma_lm": Controller("l", [], SigmaLevenbergMarquardtBackend()),
        "otmm-directional+sigma_lm": Controller(
            "dl", [DirectionAwareOtmmFilter(0.05)], SigmaLevenbergMarquardtBackend()
        ),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    robot, qs, xdots, previous = record(args.steps)
    controllers = pipelines()
    for controller in controllers.values():
        controller.bind(robot, DT)
    states = [KinematicState.compute(robot, q) for q in qs]
    active = sum(s.sigma_min <= 0.05 for s in states)
    times: dict[str, list[float]] = {name: [] for name in controllers}
    for _ in range(args.rounds):
        for name, controller in controllers.items():
            controller.reset()
            for k, q in enumerate(qs):
                start = time.perf_counter()
                state = KinematicState.compute(robot, q)
                controller.step(state, xdots[k], previous[k])
                times[name].append(time.perf_counter() - start)
    print(f"Panda pose line past the reach: {len(qs)} states, σ_min ≤ 0.05 in {active}")
    reference = float(np.median(times[REFERENCE])) * 1e6
    print(f"{'pipeline':24s} {'median µs':>10s} {'p90 µs':>8s} {'× otmm':>7s} {'+µs':>7s}")
    for name, values in times.items():
        micro = np.array(values) * 1e6
        median = float(np.median(micro))
        print(
            f"{name:24s} {median:10.1f} {np.percentile(micro, 90):8.1f} "
            f"{median / reference:7.2f} {median - reference:7.1f}"
        )
    # The cost of the direction test only matters where the filter acts: time those states.
    window = [k for k, s in enumerate(states) if s.sigma_min <= 0.05]
    if window:
        print(f"\nactive states only ({len(window)}):")
        for name in (REFERENCE, "otmm-directional+pinv"):
            controller = controllers[name]
            values = []
            for _ in range(args.rounds):
                controller.reset()
                for k in window:
                    start = time.perf_counter()
                    state = KinematicState.compute(robot, qs[k])
                    controller.step(state, xdots[k], previous[k])
                    values.append(time.perf_counter() - start)
            print(f"{name:24s} {float(np.median(values)) * 1e6:10.1f}")


if __name__ == "__main__":
    main()
