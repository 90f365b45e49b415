"""Interleaved per-step timing, summary statistics, the issue's targets and the machine."""

from __future__ import annotations

import contextlib
import importlib.metadata
import os
import platform
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from otmm_qp.bench.floor import FLOOR
from otmm_qp.bench.pipelines import (
    EVERY_STEP,
    OUR_SOLVERS,
    PEERS,
    REFERENCE,
    StepFunction,
    qp_label_solver,
)
from otmm_qp.robots.robot import FloatArray

LIBRARIES = (
    "numpy", "scipy", "pin", "qpsolvers", "daqp", "proxsuite", "osqp", "pin-pink", "mink",
    "mujoco", "drake", "roboplan-oink",
)  # fmt: skip
#: Targets on medians of one run, as fractions of :data:`REFERENCE` (issue 30).
DEFAULT_TARGET = 0.5
DAQP_TARGET = 0.38
EVERY_STEP_TARGET = 0.5
PINV_TARGET = 0.30
#: ... and of the floor (:data:`~otmm_qp.bench.floor.FLOOR`).
PINV_FLOOR_TARGET = 4.0
#: The ``otmm+qp`` pipeline held to :data:`DAQP_TARGET` (the others to DEFAULT_TARGET).
DAQP_PIPELINE = "otmm+qp (daqp, persistent)"
#: Per-step targets of the preview pipelines [µs] (issue 28): median and p99.
PREVIEW_MEDIAN_US = 1000.0
PREVIEW_P99_US = 3000.0
#: Consecutive states a pipeline runs before the next one takes over (see time_pipelines).
BLOCK = 25


@contextlib.contextmanager
def quiet_stdout() -> Iterator[None]:
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


def time_pipelines(
    pipelines: dict[str, StepFunction], steps: int, rounds: int, seed: int = 0, block: int = BLOCK
) -> dict[str, FloatArray]:
    """Per-step times [µs] of each pipeline, shape ``(rounds·steps,)``, interleaved in blocks.

    Each round walks the state sequence once in blocks of ``block`` consecutive states; every
    pipeline runs a block in turn, in a fresh random order per block. Each pipeline thus sees
    its states in order (as a control loop would, keeping caches and warm starts) and runs
    ``block`` steps in a row (warm caches), while a slow phase of the (shared, noisy) machine,
    which lasts far longer than a block, hits every pipeline alike: same-run ratios are
    steadier than with whole-sequence rounds. One untimed pass per pipeline precedes round 0
    (imports, first solver set-up).
    """
    rng = np.random.default_rng(seed)
    names = list(pipelines)
    samples = {name: np.empty((rounds, steps)) for name in names}
    clock = time.perf_counter
    size = max(block, 1)
    with quiet_stdout():
        for run in pipelines.values():
            for k in range(steps):
                run(k)
        for r in range(rounds):
            for start in range(0, steps, size):
                ks = range(start, min(start + size, steps))
                for name in rng.permutation(names):
                    run, row = pipelines[name], samples[name][r]
                    for k in ks:
                        begin = clock()
                        run(k)
                        row[k] = clock() - begin
    return {name: samples[name].ravel() * 1e6 for name in names}


def summarise(times: dict[str, FloatArray]) -> list[dict[str, Any]]:
    """Median, p10, p90, p99 [µs] and the ratios of medians to :data:`REFERENCE` and the floor.

    A ratio is NaN when its denominator was not timed.
    """
    reference = float(np.median(times[REFERENCE])) if REFERENCE in times else float("nan")
    floor = float(np.median(times[FLOOR])) if FLOOR in times else float("nan")
    rows = []
    for name, t in times.items():
        median = float(np.median(t))
        p10, p90, p99 = (float(v) for v in np.percentile(t, [10, 90, 99]))
        library = name.split(" ")[0]
        if name == FLOOR:
            library = "floor"
        elif library not in PEERS:
            library = "otmm-qp"
        rows.append(
            {
                "pipeline": name,
                "library": library,
                "median_us": median,
                "p10_us": p10,
                "p90_us": p90,
                "p99_us": p99,
                "ratio_to_pink_daqp": median / reference,
                "ratio_to_floor": median / floor,
            }
        )
    return rows


def _check(label: str, value: float, limit: float) -> dict[str, Any]:
    return {"target": label, "value_us": value, "limit_us": limit, "met": value <= limit}


def check_targets(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The issue's targets, evaluated on medians of the same run.

    * ``otmm+qp (daqp, persistent)`` ≤ 0.38 × pink (daqp); each other default
      ``otmm+qp (solver)`` ≤ 0.5 ×;
    * ``otmm+qp`` with the QP solved every step (fast path off) ≤ 0.5 × pink (daqp);
    * ``otmm+pinv`` ≤ 0.30 × pink (daqp) and ≤ 4 × the floor (when the floor was timed);
    * each ``qp`` pipeline ≤ pink with the same QP solver;
    * each ``preview`` pipeline: median ≤ 1 ms and p99 ≤ 3 ms (absolute, issue 28).
    """
    median = {row["pipeline"]: row["median_us"] for row in rows}
    reference = median.get(REFERENCE)
    if reference is None:
        return []
    checks: list[dict[str, Any]] = []
    for name, value in median.items():
        if name.startswith("otmm+qp ("):
            fraction = DEFAULT_TARGET
            if EVERY_STEP in name:
                fraction = EVERY_STEP_TARGET
            elif name == DAQP_PIPELINE:
                fraction = DAQP_TARGET
            checks.append(_check(f"{name} ≤ {fraction} × {REFERENCE}", value, fraction * reference))
    if "otmm+pinv" in median:
        checks.append(
            _check(f"otmm+pinv ≤ {PINV_TARGET} × {REFERENCE}", median["otmm+pinv"],
                   PINV_TARGET * reference)
        )  # fmt: skip
        if FLOOR in median:
            checks.append(
                _check(f"otmm+pinv ≤ {PINV_FLOOR_TARGET:g} × {FLOOR}", median["otmm+pinv"],
                       PINV_FLOOR_TARGET * median[FLOOR])
            )  # fmt: skip
    for row in rows:
        if row["pipeline"].startswith("preview"):
            name = row["pipeline"]
            checks.append(_check(f"{name} median ≤ 1 ms", row["median_us"], PREVIEW_MEDIAN_US))
            checks.append(_check(f"{name} p99 ≤ 3 ms", row["p99_us"], PREVIEW_P99_US))
    for name, value in median.items():
        solver = qp_label_solver(name)
        if solver is None:
            continue
        peer = f"pink ({OUR_SOLVERS[solver][1]})"
        if peer in median:
            checks.append(_check(f"{name} ≤ {peer}", value, median[peer]))
    return checks


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
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "load_average_1_5_15": load_average(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "versions": versions,
    }


def load_average() -> list[float]:
    """1, 5 and 15 minute load averages (NaN where the platform has none)."""
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    return [round(v, 2) for v in load]
