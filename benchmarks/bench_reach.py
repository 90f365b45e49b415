"""Certified reach of the example-robot-data arms: bound, bracket, boxes, time, offset sum.

    python benchmarks/bench_reach.py [ur5 panda z1 kinova xarm7]

Per arm: the certified reach ``outer`` [m] and the largest distance found ``found`` [m] (the
bracket of the true maximum), the chain joints searched, boxes evaluated, whether the search
met its gap, wall time [s] (first computation, no cache) and the former bound, the sum of link
offsets [m] (``PinocchioArm.reach``).
"""

from __future__ import annotations

import sys
import time

from otmm_qp.reference.chain import chain_of
from otmm_qp.reference.reach import joint_box, model_key, search_reach
from otmm_qp.robots.pinocchio_arm import PinocchioArm


def main(argv: list[str]) -> int:
    """Print one line per arm."""
    print("| arm | certified reach [m] | found [m] | joints searched | boxes | converged "
          "| s | offset sum [m] |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    for name in argv or ["ur5", "panda", "z1", "kinova", "xarm7"]:
        robot = PinocchioArm(name, task="pose")
        chain = chain_of(robot)
        lower, upper = joint_box(chain, robot)
        tic = time.perf_counter()
        found = search_reach(chain, lower, upper, model_key(chain, lower, upper))
        seconds = time.perf_counter() - tic
        cells = [f"{found.outer:.6f}", f"{found.found:.6f}", str(len(found.free))]
        cells += [str(found.boxes), str(found.converged), f"{seconds:.2f}", f"{robot.reach:.3f}"]
        print(f"| {name} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
