r"""Cost per step of the QP pipelines against pink (daqp), interleaved on the same states.

Scenario: Panda, 6-D pose task, a pose circle (radius 0.15 m, period 4 s) tracked with CLIK
(K = 10/s, dt = 0.01 s) for 4 s by ``simulate`` — the code of ``otmm-qp run`` — with plain
``qp`` (daqp); its states ``q_k``, commands ``ẋ_k`` and previous velocities are replayed.

Each pipeline step is ``KinematicState.compute`` + ``Controller.step`` (filters + backend) for
otmm-qp, and the public ``PinkBackend.solve`` alone (pink's configuration update, target and
``solve_ik`` with its limits; its ``KinematicState`` argument is built before timing) for pink,
on the same ``q_k``. Pipelines run interleaved step by step: state ``k`` is solved by every row
in turn before state ``k + 1`` (each row still sees its states in order, so warm starts are
those of a run), and the median over all steps of all rounds is reported, so the load of the
(shared, noisy) machine hits every row alike; the ratios to pink (daqp) are the result, the
absolute times are not.

Run: ``python benchmarks/bench_qp_session.py [--steps N] [--rounds R]``.
"""

from __future__ import annotations

from otmm_qp.blas_threads import prefer_single_threaded_blas

prefer_single_threaded_blas()  # before NumPy loads: one BLAS thread, as the CLI runs

import argparse  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402

import numpy as np  # noqa: E402

from otmm_qp.controller import Controller  # noqa: E402
from otmm_qp.filters.otmm import OtmmFilter  # noqa: E402
from otmm_qp.robots.pinocchio_arm import PinocchioArm  # noqa: E402
from otmm_qp.robots.robot import FloatArray  # noqa: E402
from otmm_qp.simulation import Episode, Loop, simulate  # noqa: E402
from otmm_qp.state import KinematicState  # noqa: E402
from otmm_qp.trajectories.pose import PoseCircleTrajectory  # noqa: E402
from otmm_qp_controllers.qp import QpBackend  # noqa: E402

DT = 0.01  # [s]
CLIK_GAIN = 10.0  # [1/s]
#: qp's default position limit plus the singularity barrier (the ``limits`` form).
BARRIER = [
    {"type": "position", "gain": 0.5},
    {"type": "singularity_barrier", "sigma_safe": 0.02, "gain": 1.0},
]
REFERENCE = "pink (daqp)"

Step = Callable[[int], object]


def record(steps: int) -> tuple[PinocchioArm, FloatArray, FloatArray, FloatArray]:
    """Robot, configurations (N, nq), commands (N, 6) and previous velocities (N, nv)."""
    robot = PinocchioArm(name="panda", task="pose")
    q0 = robot.configuration(np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8]))
    start = robot.kinematics(q0)[0]
    centre = np.asarray(start)[:3, 3] + np.array([0.0, 0.15, 0.0])
    trajectory = PoseCircleTrajectory(start, centre, radius=0.15, period=4.0)
    episode = Episode(robot, trajectory, q0, DT, 4.0, Loop("clik", CLIK_GAIN))
    run = simulate(episode, Controller("qp", [], QpBackend()))
    picks = np.unique(np.linspace(0, len(run.t) - 1, steps).round().astype(int))
    xdot = np.empty((picks.size, robot.task_dim))
    for i, k in enumerate(picks):
        x = robot.kinematics(run.q[k])[0]
        target, twist = trajectory.sample(float(run.t[k]))
        xdot[i] = twist + CLIK_GAIN * robot.task_error(target, x)
    prev = np.vstack([np.zeros((1, robot.nv)), run.qdot[:-1]])[picks]
    return robot, run.q[picks], xdot, prev


def otmm_step(robot: PinocchioArm, qs: FloatArray, xdots: FloatArray, prevs: FloatArray,
              otmm: bool, **options: object) -> Step:  # fmt: skip
    """``KinematicState.compute`` + ``Controller.step`` of [OTMM +] qp(**options)."""
    filters = [OtmmFilter(0.05, p="linear", corank="all")] if otmm else []
    controller = Controller("c", filters, QpBackend(**options))  # type: ignore[arg-type]
    controller.bind(robot, DT)
    compute, step = KinematicState.compute, controller.step
    return lambda k: step(compute(robot, qs[k]), xdots[k], prevs[k])


def pink_step(robot: PinocchioArm, qs: FloatArray, xdots: FloatArray, prevs: FloatArray) -> Step:
    """The public ``PinkBackend.solve`` (daqp) alone.

    Pink computes its own kinematics from ``state.q``; the states are built before timing, so
    pink's row does not pay for our ``KinematicState.compute`` (the otmm-qp rows do).
    """
    from otmm_qp_controllers.peers.pink_backend import PinkBackend

    adapter = PinkBackend(solver="daqp")
    adapter.bind(robot, DT)
    states = [KinematicState.compute(robot, q) for q in qs]
    solve = adapter.solve
    return lambda k: solve(states[k], xdots[k], prevs[k])


def pipelines(robot: PinocchioArm, qs: FloatArray, xdots: FloatArray, prevs: FloatArray
              ) -> dict[str, Step]:  # fmt: skip
    """Every timed row."""
    data = (robot, qs, xdots, prevs)
    rows: dict[str, Step] = {
        "qp (default: daqp session, fast path)": otmm_step(*data, otmm=False),
        "qp (daqp session, QP every step)": otmm_step(*data, otmm=False, fast_path=False),
        "otmm+qp (default)": otmm_step(*data, otmm=True),
        "otmm+qp (daqp session, QP every step)": otmm_step(*data, otmm=True, fast_path=False),
        "qp+barrier (default)": otmm_step(*data, otmm=False, limits=BARRIER),
        "qp+barrier (QP every step)": otmm_step(*data, otmm=False, fast_path=False, limits=BARRIER),
    }
    try:
        rows[REFERENCE] = pink_step(*data)
    except Exception as error:  # noqa: BLE001 - pink is optional: report, keep the rest
        print(f"{REFERENCE}: skipped ({error})")
    return rows


def time_interleaved(rows: dict[str, Step], count: int, rounds: int) -> dict[str, FloatArray]:
    """Per-step times [µs] of each row, rows alternating within every round."""
    samples: dict[str, list[float]] = {name: [] for name in rows}
    clock = time.perf_counter
    items = list(rows.items())
    for _ in range(rounds):
        for k in range(count):  # every state in turn, each row on it: same machine load
            shift = k % len(items)  # rotate who runs first (right after another row's work)
            for name, step in items[shift:] + items[:shift]:
                start = clock()
                step(k)
                samples[name].append(clock() - start)
    return {name: 1e6 * np.asarray(values) for name, values in samples.items()}


def main(argv: list[str] | None = None) -> int:
    """Print the table; returns 0."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=400, help="replayed states (default 400)")
    parser.add_argument("--rounds", type=int, default=5, help="interleaved rounds (default 5)")
    args = parser.parse_args(argv)
    robot, qs, xdots, prevs = record(max(args.steps, 2))
    rows = pipelines(robot, qs, xdots, prevs)
    for step in rows.values():  # warm-up: first setups, caches
        for k in range(min(len(qs), 20)):
            step(k)
    times = time_interleaved(rows, len(qs), max(args.rounds, 1))
    medians = {name: float(np.median(t)) for name, t in times.items()}
    reference = medians.get(REFERENCE)
    plain = medians["qp (default: daqp session, fast path)"]
    plain_qp = medians["qp (daqp session, QP every step)"]
    print(f"Panda pose circle, {len(qs)} states x {max(args.rounds, 1)} interleaved rounds")
    print(f"{'pipeline':44s} {'median µs':>10s} {'x pink':>8s} {'x qp':>7s}")
    for name, median in medians.items():
        versus_pink = f"{median / reference:8.2f}" if reference else f"{'-':>8s}"
        base = plain_qp if "every step" in name else plain
        print(f"{name:44s} {median:10.1f} {versus_pink} {median / base:7.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
