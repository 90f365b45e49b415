"""Where the offline reference's time goes in a study, phase by phase, and the cone solves' floor.

Run: ``python benchmarks/profile_reference.py [--tasks 200] [--config configs/studies/arms.yaml]``.

Runs the study scaled to about ``--tasks`` tasks as ``bench_reference.py`` does (one worker,
in-process) with the phases of :func:`otmm_qp.reference.solve.solve_reference` wrapped in wall
clocks (no profiler, so the Python parts are not inflated): the lower bound, the starts, the
least squares, the min-max polish, the position-only polish, the per-sample search and the
summary; inside them, Clarabel's set-up (``DefaultSolver(...)``) and solve, and OSQP's solves.
It prints each as seconds and share of the study's compute, and the **floor** the cone
programs set on the reference's share: Clarabel's seconds over (Clarabel's seconds + the
study's compute outside the reference), the share the reference would have if everything
else in it took no time.
"""

from __future__ import annotations

from otmm_qp.blas_threads import prefer_single_threaded_blas

prefer_single_threaded_blas()  # before NumPy loads: one BLAS thread, as the CLI runs

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections import defaultdict  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import clarabel  # noqa: E402

from otmm_qp.reference import conic, solve, sqp  # noqa: E402
from otmm_qp.studies import oracle  # noqa: E402
from otmm_qp.studies.execute import run_study  # noqa: E402
from otmm_qp.studies.spec import plan_study  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_reference import DEFAULT_CONFIG, scaled  # noqa: E402

#: The phases of ``solve_reference`` timed (module-level functions of ``reference.solve``).
PHASES = (
    "lower_bound",
    "_starts",
    "_least_squares",
    "_polish",
    "_position_optimum",
    "_search_samples",
    "summarise",
)

_TOTALS: dict[str, float] = defaultdict(float)


def _timed(function: Callable[..., Any], name: str) -> Callable[..., Any]:
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        tic = time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            _TOTALS[name] += time.perf_counter() - tic

    return wrapper


class _TimedClarabel:
    """``clarabel`` as the cone polish sees it, with its set-up and solve timed."""

    SecondOrderConeT = clarabel.SecondOrderConeT
    NonnegativeConeT = clarabel.NonnegativeConeT
    DefaultSettings = clarabel.DefaultSettings

    class DefaultSolver:
        def __init__(self, *args: Any) -> None:
            tic = time.perf_counter()
            self._solver = clarabel.DefaultSolver(*args)
            _TOTALS["  Clarabel set-up"] += time.perf_counter() - tic

        def solve(self) -> Any:
            tic = time.perf_counter()
            try:
                return self._solver.solve()
            finally:
                _TOTALS["  Clarabel solve"] += time.perf_counter() - tic


def main(argv: list[str] | None = None) -> int:
    """Run the scaled study with the phases timed and print the table."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--tasks", type=int, default=200, help="about this many tasks; 0: all")
    parser.add_argument("--config", type=Path, default=DEFAULT_CONFIG)
    args = parser.parse_args(argv)
    for name in PHASES:
        setattr(solve, name, _timed(getattr(solve, name), name))
    # the study calls it through ``oracle`` (bound at import there)
    oracle.solve_reference = _timed(oracle.solve_reference, "reference (solve_reference)")
    conic.clarabel = _TimedClarabel  # type: ignore[assignment]
    sqp.SequentialQP._solve = _timed(sqp.SequentialQP._solve, "  OSQP solve")  # type: ignore[method-assign]
    config = scaled(args.config, args.tasks)
    plan = plan_study(config, str(args.config))
    with tempfile.TemporaryDirectory() as scratch:
        outcome = run_study(plan, Path(scratch) / "study", "profile", workers=1)
    compute = outcome.compute_seconds
    reference = _TOTALS["reference (solve_reference)"]
    print(f"{args.config.name}: {outcome.ran} episodes, study compute {compute:.1f} s")
    print("| phase | s | % of compute |")
    print("|---|---|---|")
    for name, seconds in sorted(_TOTALS.items(), key=lambda item: -item[1]):
        print(f"| {name} | {seconds:.3f} | {100 * seconds / compute:.1f} |")
    cones = _TOTALS["  Clarabel set-up"] + _TOTALS["  Clarabel solve"]
    rest = compute - reference
    print(f"reference {reference:.1f} s = {100 * reference / compute:.1f} % of compute; "
          f"floor set by the cone programs: {cones:.1f} s / ({cones:.1f} + {rest:.1f}) s "
          f"= {100 * cones / (cones + rest):.1f} %")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
