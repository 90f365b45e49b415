"""The control step's memory traffic stays small (issue 30): measured, never timed.

``tracemalloc`` records every Python and NumPy allocation. For each pipeline on the Panda, a
first pass over a path toward the stretched-elbow singularity runs every code path once
(solver set-up, buffers allocated at bind or on first use); three more passes measure, per
``Controller.step`` (filters + backend + the NaN/speed guards), the transient high-water mark
of traced memory above what was live before the step (the least of the three per step). A
step allocates only what it returns (``q̇``, ``ẋ_m`` when a filter acts, the small result
tuples) and what the QP solver's binding allocates itself; a temporary array per operation,
as before issue 30, roughly doubles or triples the figure (the measured values are beside each
case). The bounds sit between the two with headroom for NumPy's object sizes on other
versions; nothing here depends on the speed of the machine.
"""

from __future__ import annotations

import statistics
import tracemalloc
from collections import Counter
from typing import Any

import numpy as np
import pytest

from otmm_qp import registry
from otmm_qp.controller import Controller
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.robots.robot import FloatArray
from otmm_qp.state import KinematicState

DT = 0.01
STEPS = 60


def _path(robot: PinocchioArm) -> tuple[list[KinematicState], list[FloatArray]]:
    """States from the ready pose toward a stretched elbow, and pose commands.

    σ_min falls from 0.21 to about 1e-3 mid-path (the OTMM filter acts on the last third);
    the commands alternate a slow and a fast one (the QP's fast path and its solver, pinv's
    ``ok`` and ``saturated``).
    """
    start = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
    stretched = np.array([0.0, 0.3, 0.0, -0.08, 0.0, 1.6, 0.8])  # elbow at its limit, near straight
    states, commands = [], []
    for k, s in enumerate(np.linspace(0.0, 1.0, STEPS)):
        theta = (1.0 - s) * start + s * stretched
        states.append(KinematicState.compute(robot, robot.configuration(theta)))
        scale = 0.05 if k % 2 else 0.8
        commands.append(scale * np.array([1.0, 0.2, -0.3, 0.1, -0.2, 0.3]))
    return states, commands


def _controller(
    backend: str, params: dict[str, Any], otmm: bool, robot: PinocchioArm
) -> Controller:
    filters = []
    if otmm:
        params_otmm = {"sigma_s": 0.05, "p": "linear", "corank": "all"}
        filters.append(registry.create(registry.FILTERS, "otmm", params_otmm, "otmm"))
    controller = Controller(
        backend, filters, registry.create(registry.BACKENDS, backend, params, backend)
    )
    controller.bind(robot, DT)
    return controller


def _step_peaks(
    controller: Controller, states: list[KinematicState], commands: list[FloatArray]
) -> tuple[list[int], Counter[str]]:
    """Per-step peak of traced memory above the memory live before the step [bytes].

    ``tracemalloc`` traces every thread, so a thread left running by another test could add
    its allocations to a step's window: each step's figure is the least of three passes.
    """

    def run_pass(peaks: list[int] | None) -> Counter[str]:
        seen: Counter[str] = Counter()
        qdot_prev = np.zeros(states[0].jacobian.shape[1])
        for state, command in zip(states, commands, strict=True):
            if peaks is not None:
                before = tracemalloc.get_traced_memory()[0]
                tracemalloc.reset_peak()
            output = controller.step(state, command, qdot_prev)
            if peaks is not None:
                peaks.append(tracemalloc.get_traced_memory()[1] - before)
            active = any(report.active for report in output.reports)
            seen[f"{output.backend.status}{'+filtered' if active else ''}"] += 1
            assert np.all(np.isfinite(output.qdot))
            qdot_prev = output.qdot
        return seen

    run_pass(None)  # warm-up: every path once
    passes: list[list[int]] = [[], [], []]
    tracemalloc.start()
    try:
        seen = Counter[str]()
        for peaks in passes:
            seen = run_pass(peaks)
    finally:
        tracemalloc.stop()
    return [min(values) for values in zip(*passes, strict=True)], seen


@pytest.fixture(scope="module")
def panda_path() -> tuple[PinocchioArm, list[KinematicState], list[FloatArray]]:
    robot = PinocchioArm(name="panda", task="pose")
    return (robot, *_path(robot))


@pytest.mark.parametrize(
    ("backend", "params", "otmm", "median_bound", "max_bound", "paths"),
    [
        # measured: median 488 B, max 632 B (before issue 30: 1,337 B, 1,481 B)
        ("pinv", {}, True, 800, 1200, ("ok", "saturated")),
        # measured: median 368 B, max 408 B (before: 1,225 B, 1,257 B)
        ("dls", {"damping": 0.05}, False, 700, 1000, ("ok", "saturated")),
        # measured: median 704 B (before: 1,384 B); the steps that reach DAQP add what its
        # binding allocates (max 1,416 B)
        ("qp", {"solver": "daqp"}, True, 1100, 3200, ("ok", "bounded")),
        # the QP every step: DAQP's binding dominates (median 1,232 B, max 1,376 B; before:
        # 1,376 B); the QP's own arrays are written in place, the solver's x is returned
        # unclipped when inside the box (no copy)
        ("qp", {"solver": "daqp", "fast_path": False}, True, 1700, 3200, ("ok", "bounded")),
    ],
)
def test_a_step_allocates_only_what_it_returns(
    panda_path: tuple[PinocchioArm, list[KinematicState], list[FloatArray]],
    backend: str,
    params: dict[str, Any],
    otmm: bool,
    median_bound: int,
    max_bound: int,
    paths: tuple[str, ...],
) -> None:
    robot, states, commands = panda_path
    peaks, seen = _step_peaks(_controller(backend, params, otmm, robot), states, commands)
    # The path exercises the code it is meant to (not a vacuous pass).
    for path in paths:
        assert any(key.startswith(path) for key in seen), (path, seen)
    if otmm:
        assert any(key.endswith("+filtered") for key in seen), seen
    assert statistics.median(peaks) <= median_bound, (statistics.median(peaks), seen)
    assert max(peaks) <= max_bound, (max(peaks), seen)


def test_steps_retain_nothing(
    panda_path: tuple[PinocchioArm, list[KinematicState], list[FloatArray]],
) -> None:
    """Memory live after 3 passes (180 steps) equals memory live before: no per-step growth.

    The least of three such measurements (another test's leftover thread may allocate while
    ``tracemalloc`` traces).
    """
    robot, states, commands = panda_path
    controller = _controller("qp", {"solver": "daqp"}, True, robot)
    _step_peaks(controller, states, commands)  # warm-up included
    growth = []
    for _ in range(3):
        tracemalloc.start()
        try:
            before = tracemalloc.get_traced_memory()[0]
            for _ in range(3):
                qdot_prev = np.zeros(robot.nv)
                for state, command in zip(states, commands, strict=True):
                    qdot_prev = controller.step(state, command, qdot_prev).qdot
            del qdot_prev
            growth.append(tracemalloc.get_traced_memory()[0] - before)
        finally:
            tracemalloc.stop()
    assert min(growth) <= 1024, growth  # a leak of one small array per step is 30 KB here
