"""Time one control step on Panda with a 6-D pose task, limits inactive and active.

Pipelines (KinematicState.compute + OTMM filter + backend, via ``Controller.step``) are built
through the registry from their YAML parameters. Pure timing, no assertions.
Run: ``python benchmarks/bench_arm_step.py [--steps N]``; prints median / p90 [µs] per line.
"""

from __future__ import annotations

from otmm_qp.blas_threads import prefer_single_threaded_blas

prefer_single_threaded_blas()  # before NumPy loads: one BLAS thread, as the CLI runs

import argparse  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

from otmm_qp import registry  # noqa: E402
from otmm_qp.controller import Controller  # noqa: E402
from otmm_qp.robots.robot import Robot  # noqa: E402
from otmm_qp.state import KinematicState  # noqa: E402

DT = 0.01  # [s]
THETA = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])  # Panda ready pose [rad]
#: label -> (backend, YAML parameters); each runs behind OTMM (σ_S = 0.05, corank all).
PIPELINES: dict[str, tuple[str, dict[str, Any]]] = {
    "otmm+pinv": ("pinv", {}),
    "otmm+qp (daqp, persistent)": ("qp", {"solver": "daqp"}),
    "otmm+qp (daqp, persistent, QP every step)": ("qp", {"solver": "daqp", "fast_path": False}),
    "otmm+qp (proxsuite, persistent)": ("qp", {"solver": "proxsuite"}),
}


def controller(label: str, backend: str, params: dict[str, Any]) -> Controller:
    otmm = registry.create(registry.FILTERS, "otmm", {"sigma_s": 0.05, "corank": "all"}, label)
    return Controller(label, [otmm], registry.create(registry.BACKENDS, backend, params, label))


def percentiles(samples: np.ndarray, warm_up: int) -> tuple[float, float]:
    """Median and p90 [µs] of ``samples`` [s] after the first ``warm_up``."""
    kept = samples[warm_up:] * 1e6
    return float(np.median(kept)), float(np.percentile(kept, 90))


def time_calls(call: Callable[[int], None], steps: int) -> np.ndarray:
    samples = np.empty(steps)
    for k in range(steps):
        start = time.perf_counter()
        call(k)
        samples[k] = time.perf_counter() - start
    return samples


def time_controller(pipeline: Controller, robot: Robot, speed: float, steps: int) -> np.ndarray:
    """Step times [s] at one configuration for random commands of RMS ``speed`` [m/s, rad/s]."""
    pipeline.bind(robot, DT)
    q = robot.configuration(THETA)
    qdot = np.zeros(robot.nv)
    xdots = speed * np.random.default_rng(0).standard_normal((steps, 6))
    return time_calls(
        lambda k: pipeline.step(KinematicState.compute(robot, q), xdots[k], qdot), steps
    )


def main(argv: Sequence[str] | None = None) -> dict[str, tuple[float, float]]:
    """Print and return ``label -> (median µs, p90 µs)``."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--steps", type=int, default=3000, help="timed steps per line")
    steps = parser.parse_args(argv).steps
    warm_up = min(200, steps // 10)
    robot = registry.create(registry.ROBOTS, "pinocchio", {"name": "panda", "task": "pose"}, "")
    q = robot.configuration(THETA)
    lines = {
        "KinematicState.compute": time_calls(lambda k: KinematicState.compute(robot, q), steps),
        "robot.kinematics": time_calls(lambda k: robot.kinematics(q), steps),
    }
    for speed, regime in [(0.05, "limits inactive"), (5.0, "limits active")]:
        for label, (backend, params) in PIPELINES.items():
            samples = time_controller(controller(label, backend, params), robot, speed, steps)
            lines[f"{label} [{regime}]"] = samples
    results = {label: percentiles(samples, warm_up) for label, samples in lines.items()}
    for label, (median, p90) in results.items():
        print(f"{label:50s} median {median:7.1f} µs  p90 {p90:7.1f} µs")
    return results


if __name__ == "__main__":
    main()
