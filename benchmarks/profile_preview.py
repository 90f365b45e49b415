"""Where one preview step's CPU time goes, phase by phase, on the Panda bench scenario.

Run: ``python benchmarks/profile_preview.py [--row LABEL] [--steps N] [--rounds R] [--cprofile]``.
Replays the recorded states of ``bench_preview_cpu.py`` through one preview pipeline of
:data:`otmm_qp.bench.pipelines.PREVIEWS` (default: ``preview-minmax (16 knots)``) and charges
the CPU time of this thread (``time.thread_time``) to each phase of
:meth:`PreviewBackend.plan_slices`: the step's box, the knots' kinematics (FK + Jacobian per
knot), the targets, the QP's assembly (Hessian and gradient), the fast-path candidates, the
solver's load (set-up or update: DAQP's factorisation of ``P`` and ``M = C R⁻¹`` over every
row) and its solve (the active-set iterations); what is left is the state (kinematics + SVD),
the nominal's shift, the clip into the box and Python. With ``--cprofile`` the cProfile table
of the same replay follows (top 25 by own time).
"""

from __future__ import annotations

from otmm_qp.blas_threads import prefer_single_threaded_blas

prefer_single_threaded_blas()  # before NumPy loads: one BLAS thread, as the CLI runs

import argparse  # noqa: E402
import cProfile  # noqa: E402
import pstats  # noqa: E402
import time  # noqa: E402
from collections import defaultdict  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from typing import Any  # noqa: E402

from otmm_qp.bench.pipelines import PREVIEWS, build_steps  # noqa: E402
from otmm_qp.bench.scenarios import panda_scenario  # noqa: E402
from otmm_qp_controllers.preview import backend as preview_backend  # noqa: E402
from otmm_qp_controllers.preview import formulation  # noqa: E402
from otmm_qp_controllers.preview.backend import PreviewBackend  # noqa: E402

#: The phases timed: (what is wrapped, its attribute, the phase's name).
_PHASES: tuple[tuple[Any, str, str], ...] = (
    (preview_backend.PreviewBackend, "begin_step", "box (begin_step)"),
    (preview_backend.PreviewBackend, "_linearise", "knots' FK + Jacobians"),
    (preview_backend.TrajectoryTargets, "residuals", "targets (x_d, task error)"),
    (preview_backend.TrajectoryTargets, "speed", "window speed (peak_scale: arm)"),
    (formulation.PreviewProblem, "build", "QP assembly (Hessian, gradient)"),
    (formulation.PreviewProblem, "with_active_bounds", "fast-path candidates"),
    (formulation.PreviewProblem, "with_active_set", "warm active set (bounds and rows)"),
    (formulation.PreviewProblem, "active_bounds", "active-bound masks"),
    (formulation.PreviewProblem, "active_rows", "active-row masks"),
    (formulation.PreviewProblem, "violated_rows", "broken-row checks"),
)


def _timed(
    function: Callable[..., Any], name: str, spent: dict[str, float], depth: list[int]
) -> Any:
    """``function`` charging its CPU time to ``name`` (only when no other phase is running)."""
    clock = time.thread_time

    def wrapper(*args: Any, **kwargs: Any) -> Any:
        depth[0] += 1
        begin = clock()
        try:
            return function(*args, **kwargs)
        finally:
            depth[0] -= 1
            if not depth[0]:  # a phase inside another is the outer one's
                spent[name] += clock() - begin

    return wrapper


def _patch(spent: dict[str, float], session: Any) -> list[tuple[Any, str, Any]]:
    """Wrap the phases' functions (and the session's load and solve); the originals."""
    saved, depth = [], [0]
    for owner, attribute, name in _PHASES:
        original = getattr(owner, attribute)
        saved.append((owner, attribute, original))
        setattr(owner, attribute, _timed(original, name, spent, depth))
    for attribute, name in (("load", "solver load (set-up/update)"), ("solve", "solver solve")):
        original = getattr(session, attribute)
        saved.append((session, attribute, None))
        setattr(session, attribute, _timed(original, name, spent, depth))
    return saved


def main(argv: Sequence[str] | None = None) -> int:
    """Profile one preview pipeline and print the phase table."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    labels = [label for label, _, _ in PREVIEWS]
    parser.add_argument("--row", default="preview-minmax (16 knots)", choices=labels)
    parser.add_argument("--steps", type=int, default=300, help="replayed states (default 300)")
    parser.add_argument("--rounds", type=int, default=3, help="rounds (default 3)")
    parser.add_argument("--cprofile", action="store_true", help="also print cProfile's table")
    args = parser.parse_args(argv)
    scenario = panda_scenario(args.steps)
    built, _ = build_steps(scenario, True, only=[args.row])
    run = built[args.row]
    backend = next(  # the replay closes over the backend's bound ``seek``
        cell.cell_contents.__self__
        for cell in run.__closure__ or ()
        if isinstance(getattr(cell.cell_contents, "__self__", None), PreviewBackend)
    )
    for k in range(scenario.steps):  # one untimed pass
        run(k)
    spent: dict[str, float] = defaultdict(float)
    saved = _patch(spent, backend.session)
    total = args.rounds * scenario.steps
    solver_calls = 0
    original_solve = backend.session.solve

    def counting() -> Any:
        nonlocal solver_calls
        solver_calls += 1
        return original_solve()

    backend.session.solve = counting
    begin = time.thread_time()
    for i in range(total):
        run(i % scenario.steps)
    whole = time.thread_time() - begin
    for owner, attribute, original in saved:
        if original is None:
            delattr(owner, attribute)
        else:
            setattr(owner, attribute, original)
    print(
        f"{args.row}: {total} steps, {whole / total * 1e6:.0f} µs CPU per step, "
        f"{solver_calls / total:.2f} solver calls per step"
    )
    print("| phase | µs per step | share |")
    print("|---|---|---|")
    for name, seconds in sorted(spent.items(), key=lambda item: -item[1]):
        print(f"| {name} | {seconds / total * 1e6:.0f} | {100 * seconds / whole:.0f} % |")
    rest = whole - sum(spent.values())
    print(
        f"| the rest (state, filters, shift, clip, Python) | {rest / total * 1e6:.0f} | "
        f"{100 * rest / whole:.0f} % |"
    )
    if args.cprofile:
        profiler = cProfile.Profile(time.thread_time)
        profiler.enable()
        for i in range(total):
            run(i % scenario.steps)
        profiler.disable()
        pstats.Stats(profiler).sort_stats("tottime").print_stats(25)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
