"""Instructions per control step, counted by valgrind (load-independent; see PERFORMANCE.md).

Run: ``python benchmarks/bench_instructions.py [--steps N] [--passes P] [--no-valgrind]``.

The floor, ``KinematicState.compute``, four pipelines (OTMM + pinv, dls, OTMM + QP, OTMM +
QP solved every step; each ``KinematicState.compute`` + ``Controller.step``) and pink with
daqp (its adapter's public ``solve`` on the step's state, as the bench times it) run the
bench's recorded Panda states, each after one untimed warm-up pass, in phases marked by
``os.getpid()``. Under ``valgrind --tool=callgrind --dump-before=getpid`` (what this script
starts when valgrind is installed, unless ``--no-valgrind``) every phase is one dump, so the
instructions of a phase divided by its steps is the count per step, whatever else the
machine is doing. Without valgrind the phases only run (a quick check). Uses only APIs older
than the floor row, so the same script counts the code of an earlier commit too.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

PHASES = ("floor", "compute", "otmm+pinv", "dls", "otmm+qp", "otmm+qp every step", "pink (daqp)")


def _steps(steps: int) -> dict[str, Callable[[int], None]]:
    """The step function of every phase on ``steps`` recorded Panda states."""
    import pinocchio as pin
    from scipy.linalg import lapack

    from otmm_qp import registry
    from otmm_qp.bench.scenarios import DT, otmm_controller, panda_scenario
    from otmm_qp.controller import Controller
    from otmm_qp.state import KinematicState

    scenario = panda_scenario(steps)
    robot, qs, xdots, prevs = scenario.robot, scenario.q, scenario.xdot, scenario.qdot_prev
    model, data, frame = robot.model, robot.data, robot.frame_id  # type: ignore[attr-defined]
    rows, nv = robot.task_dim, robot.nv
    k_min = min(rows, nv)
    lwork = 4 * k_min * k_min + max(rows, nv) + 9 * k_min

    def floor(k: int) -> None:
        pin.forwardKinematics(model, data, qs[k])
        pin.updateFramePlacement(model, data, frame)
        jacobian = pin.computeFrameJacobian(model, data, qs[k], frame, pin.LOCAL_WORLD_ALIGNED)
        lapack.dgesdd(jacobian, 1, 0, lwork, 1)

    def compute(k: int) -> None:
        KinematicState.compute(robot, qs[k])

    def pipeline(backend: str, params: dict[str, object], otmm: bool) -> Callable[[int], None]:
        if otmm:
            controller = otmm_controller(backend, backend, params)
        else:
            solver = registry.create(registry.BACKENDS, backend, params, backend)
            controller = Controller(backend, [], solver)
        controller.bind(robot, DT)

        def run(k: int) -> None:
            controller.step(KinematicState.compute(robot, qs[k]), xdots[k], prevs[k])

        return run

    def peer(name: str, params: dict[str, object]) -> Callable[[int], None]:
        # As the bench times a peer: its public solve on the step's state (pink's own
        # configuration update, task, limits and QP inside).
        adapter = registry.create(registry.BACKENDS, name, params, name)
        adapter.bind(robot, DT)
        adapter.reset()
        states = [KinematicState.compute(robot, q) for q in qs]

        def run(k: int) -> None:
            adapter.solve(states[k], xdots[k], prevs[k])

        return run

    daqp: dict[str, object] = {"solver": "daqp"}
    return dict(
        zip(
            PHASES,
            (
                floor,
                compute,
                pipeline("pinv", {}, True),
                pipeline("dls", {"damping": 0.05}, False),
                pipeline("qp", daqp, True),
                pipeline("qp", {**daqp, "fast_path": False}, True),
                peer("pink", daqp),
            ),
            strict=True,
        )
    )


def run_phases(steps: int, passes: int) -> None:
    """Warm every phase up, then run each for ``passes`` passes between two ``getpid`` marks."""
    runs = _steps(steps)
    for run in runs.values():
        for k in range(steps):
            run(k)
    for run in runs.values():
        os.getpid()
        for _ in range(passes):
            for k in range(steps):
                run(k)
    os.getpid()


def counted(steps: int, passes: int) -> dict[str, float]:
    """Run :func:`run_phases` under callgrind; instructions per step of each phase."""
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "callgrind.out"
        command = [
            "valgrind", "--tool=callgrind", "--dump-before=getpid",
            f"--callgrind-out-file={out}", sys.executable, __file__,
            "--steps", str(steps), "--passes", str(passes), "--no-valgrind",
        ]  # fmt: skip
        subprocess.run(command, check=True, capture_output=True)
        dumps = sorted(Path(folder).glob("callgrind.out.*"), key=lambda p: int(p.suffix[1:]))
        totals = [int(re.search(r"^summary: (\d+)", p.read_text(), re.M).group(1))  # type: ignore[union-attr]
                  for p in dumps]  # fmt: skip
    # dump 1: start-up and warm-up; then one dump per phase
    return {name: totals[1 + i] / (steps * passes) for i, name in enumerate(PHASES)}


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the arguments, count (or only run) the phases, print one line per phase."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--steps", type=int, default=300, help="recorded Panda states (>= 10)")
    parser.add_argument("--passes", type=int, default=2, help="counted passes per phase (>= 1)")
    parser.add_argument("--no-valgrind", action="store_true", help="only run the phases")
    args = parser.parse_args(argv)
    if args.steps < 10 or args.passes < 1:
        parser.error("--steps must be >= 10 and --passes >= 1")
    if args.no_valgrind or shutil.which("valgrind") is None:
        run_phases(args.steps, args.passes)
        print(
            f"ran {len(PHASES)} phases x {args.passes} passes x {args.steps} states (not counted)"
        )
        return 0
    per_step = counted(args.steps, args.passes)
    floor, pink = per_step["floor"], per_step["pink (daqp)"]
    for name, value in per_step.items():
        print(
            f"{name:20s} {value / 1e3:8.1f} k instructions/step  {value / floor:5.2f} x floor"
            f"  {value / pink:5.3f} x pink"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
