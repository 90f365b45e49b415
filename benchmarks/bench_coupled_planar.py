"""What the speed-coupled certificate decides where its boxes are small: random planar tasks.

    python benchmarks/bench_coupled_planar.py [--tasks 60]

Task ``i`` (seed ``i``): a planar arm of 2 (even ``i``) or 3 (odd) links of 0.3–0.9 m,
joints at most 1.5 rad/s, from a random start along a line to a random point at 0.3–1.3 ×
the arm's length in 0.4–1.5 s (held 0.1 s), tolerance 0.02 m, ``dt`` = 0.02 s. Each task's
reference (:func:`otmm_qp.reference.solve_reference`) is labelled; a ``coupled@k``
certificate (:mod:`otmm_qp.reference.coupled_bound`) is only sought on a task every other
bound leaves undecided, so "without" counts those tasks as undecided.
"""

from __future__ import annotations

from otmm_qp.blas_threads import prefer_single_threaded_blas

prefer_single_threaded_blas()  # before NumPy loads: one BLAS thread, as the CLI runs

import argparse  # noqa: E402
import time  # noqa: E402
from collections import Counter  # noqa: E402

import numpy as np  # noqa: E402

from otmm_qp.reference import ReferenceSettings, solve_reference  # noqa: E402
from otmm_qp.robots.planar_arm import PlanarArm  # noqa: E402
from otmm_qp.trajectories.waypoints import WaypointsTrajectory  # noqa: E402

DT = 0.02  # [s]
SPEED = 1.5  # [rad/s]


def main(argv: list[str] | None = None) -> int:
    """Label ``--tasks`` random planar tasks and print the labels with and without ``coupled``."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--tasks", type=int, default=60)
    args = parser.parse_args(argv)
    settings = ReferenceSettings(position_tolerance=0.02, speed_limit=SPEED)
    labels: Counter[str] = Counter()
    without: Counter[str] = Counter()
    kinds: Counter[str] = Counter()
    tic = time.process_time()
    for seed in range(args.tasks):
        rng = np.random.default_rng(seed)
        links = 2 + seed % 2
        lengths = list(rng.uniform(0.3, 0.9, links))
        reach = rng.uniform(0.3, 1.3)
        robot = PlanarArm(lengths, velocity_limits=[SPEED] * links)
        q0 = rng.uniform(-2.0, 2.0, links)
        angle = rng.uniform(-np.pi, np.pi)
        goal = reach * sum(lengths) * np.array([np.cos(angle), np.sin(angle)])
        duration = rng.uniform(0.4, 1.5)
        trajectory = WaypointsTrajectory(robot.forward(q0), [goal], duration=duration)
        result, _ = solve_reference(robot, trajectory, q0, DT, duration + 0.1, settings)
        kind = result.bracket.certificate.split("@")[0]
        labels[result.status] += 1
        coupled = result.status == "unachievable" and kind == "coupled"
        without["undecided" if coupled else result.status] += 1
        if result.status == "unachievable":
            kinds[kind] += 1
    order = ("achievable", "unachievable", "undecided", "failed")
    print(f"{args.tasks} planar tasks, {time.process_time() - tic:.1f} s CPU")
    print("labels without coupled: " + ", ".join(f"{s} {without[s]}" for s in order))
    print("labels with coupled:    " + ", ".join(f"{s} {labels[s]}" for s in order))
    listed = ", ".join(f"{kind} {count}" for kind, count in sorted(kinds.items()))
    print(f"certificates of unachievable tasks: {listed}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
