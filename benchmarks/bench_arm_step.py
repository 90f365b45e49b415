"""Time one control step on Panda with a 6-D pose task (pure timing, no assertions).

Pipelines: KinematicState.compute + OTMM filter + backend, via ``Controller.step``.
Run: ``python benchmarks/bench_arm_step.py``; prints median / p90 [µs] per pipeline.
"""

from __future__ import annotations

import time

import numpy as np

from otmm_qp.controller import Controller
from otmm_qp.filters.otmm import OtmmFilter
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.state import KinematicState
from otmm_qp_controllers.pinv import PseudoInverseBackend
from otmm_qp_controllers.qp import QpBackend

STEPS = 3000
DT = 0.01  # [s]


def pipelines() -> dict[str, Controller]:
    return {
        "otmm+pinv": Controller(
            "otmm+pinv", [OtmmFilter(0.05, corank="all")], PseudoInverseBackend()
        ),
        "otmm+qp(direct_proxsuite)": Controller(
            "otmm+qp", [OtmmFilter(0.05, corank="all")], QpBackend(solver="direct_proxsuite")
        ),
        "otmm+qp(direct_proxsuite, no fast path)": Controller(
            "otmm+qp-nofast",
            [OtmmFilter(0.05, corank="all")],
            QpBackend(solver="direct_proxsuite", fast_path=False),
        ),
        "otmm+qp(daqp)": Controller("otmm+qp", [OtmmFilter(0.05, corank="all")], QpBackend()),
    }


def run(controller: Controller, robot: PinocchioArm, speed: float) -> np.ndarray:
    controller.bind(robot, DT)
    theta = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
    q = robot.configuration(theta)
    qdot = np.zeros(robot.nv)
    rng = np.random.default_rng(0)
    xdots = speed * rng.standard_normal((STEPS, 6))
    timings = np.empty(STEPS)
    for k in range(STEPS):
        start = time.perf_counter()
        state = KinematicState.compute(robot, q)
        out = controller.step(state, xdots[k], qdot)
        timings[k] = time.perf_counter() - start
        qdot = out.qdot
        q = robot.integrate(q, 0.0 * qdot, DT)  # stay at one configuration region
    return timings[200:] * 1e6


def main() -> None:
    robot = PinocchioArm(name="panda", task="pose")
    q = robot.configuration(np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8]))
    for label, fn in [
        ("KinematicState.compute", lambda: KinematicState.compute(robot, q)),
        ("robot.kinematics", lambda: robot.kinematics(q)),
    ]:
        samples = np.empty(STEPS)
        for k in range(STEPS):
            start = time.perf_counter()
            fn()
            samples[k] = time.perf_counter() - start
        samples = samples[200:] * 1e6
        p90 = np.percentile(samples, 90)
        print(f"{label:45s} median {np.median(samples):6.1f} µs  p90 {p90:6.1f} µs")
    for speed, regime in [(0.05, "limits inactive"), (5.0, "limits active")]:
        for name, controller in pipelines().items():
            t = run(controller, robot, speed)
            label = f"{name} [{regime}]"
            print(f"{label:45s} median {np.median(t):6.1f} µs  p90 {np.percentile(t, 90):6.1f} µs")


if __name__ == "__main__":
    main()
