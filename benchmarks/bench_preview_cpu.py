"""Per-step CPU time of the preview pipelines beside pink (daqp), immune to other processes.

Run: ``python benchmarks/bench_preview_cpu.py [--steps N] [--rounds R] [--deployable]``
(``--deployable``: only pink (daqp) and the deployable row are built and timed). The Panda
pipelines of ``otmm-qp bench`` (:data:`otmm_qp.bench.pipelines.PREVIEWS` — every preview row
a study or the README names — and ``pink (daqp)``) replay the same recorded states, each in
order (one untimed pass, then ``R`` rounds), timed with ``time.thread_time`` — the CPU time of
this thread, so a step preempted by another process is not charged for the wait — and, beside
it, with ``time.perf_counter`` (wall clock, which a loaded machine inflates). On a shared
machine the wall-clock p99 measures the scheduler (a 4 ms time slice lands in 1–10 % of
steps); the CPU p99 is the step's own worst case. Prints a Markdown table: CPU median, p99
and max [µs], wall median and p99 [µs], and the CPU medians' and p99s' ratios to pink (daqp)
of the same run; then whether the deployable row
(:data:`~otmm_qp.bench.pipelines.DEPLOYABLE`) meets its budget, CPU median ≤ 1 ms and p99 ≤ 2 ms.
"""

from __future__ import annotations

from otmm_qp.blas_threads import prefer_single_threaded_blas

prefer_single_threaded_blas()  # before NumPy loads: one BLAS thread, as the CLI runs

import argparse  # noqa: E402
import time  # noqa: E402
from collections.abc import Sequence  # noqa: E402

import numpy as np  # noqa: E402

from otmm_qp.bench.pipelines import DEPLOYABLE, PREVIEWS, REFERENCE, build_steps  # noqa: E402
from otmm_qp.bench.scenarios import panda_scenario  # noqa: E402

#: The deployable row's budget: CPU median and p99 per step [µs].
BUDGET = (1000.0, 2000.0)


def step_times(
    steps: int, rounds: int, deployable: bool = False
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """CPU and wall time [µs] of every step, each shape ``(rounds·steps,)``, per pipeline.

    ``deployable``: pink (daqp) and :data:`DEPLOYABLE` only.
    """
    scenario = panda_scenario(steps)
    previews = [DEPLOYABLE] if deployable else [label for label, _, _ in PREVIEWS]
    wanted = [REFERENCE, *previews]
    built, _ = build_steps(scenario, True, only=wanted)
    cpu, wall = time.thread_time, time.perf_counter
    out = {}
    for name in (n for n in wanted if n in built):
        run = built[name]
        for k in range(scenario.steps):
            run(k)
        samples = np.empty((2, rounds * scenario.steps))
        for i in range(samples.shape[1]):
            begin, start = cpu(), wall()
            run(i % scenario.steps)
            samples[1, i] = wall() - start
            samples[0, i] = cpu() - begin
        out[name] = (samples[0] * 1e6, samples[1] * 1e6)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Time the pipelines and print the table."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--steps", type=int, default=300, help="replayed states (default 300)")
    parser.add_argument("--rounds", type=int, default=3, help="rounds (default 3)")
    parser.add_argument(
        "--deployable", action="store_true", help="time pink (daqp) and the deployable row only"
    )
    args = parser.parse_args(argv)
    times = step_times(args.steps, args.rounds, args.deployable)
    reference = times[REFERENCE][0] if REFERENCE in times else None
    print(
        "| pipeline | CPU median µs | CPU p99 µs | CPU max µs | wall median µs | wall p99 µs "
        "| CPU median × pink | CPU p99 × pink |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name, (v, w) in times.items():
        median, p99 = float(np.median(v)), float(np.percentile(v, 99))
        ratios = (
            (median / float(np.median(reference)), p99 / float(np.percentile(reference, 99)))
            if reference is not None
            else (float("nan"), float("nan"))
        )
        print(
            f"| {name} | {median:.0f} | {p99:.0f} | {v.max():.0f} | {np.median(w):.0f} | "
            f"{np.percentile(w, 99):.0f} | {ratios[0]:.2f} | {ratios[1]:.2f} |"
        )
    if DEPLOYABLE in times:
        v = times[DEPLOYABLE][0]
        median, p99 = float(np.median(v)), float(np.percentile(v, 99))
        meets = median <= BUDGET[0] and p99 <= BUDGET[1]
        print(
            f"\n{DEPLOYABLE}: CPU median {median:.0f} µs (≤ {BUDGET[0]:.0f}), p99 {p99:.0f} µs "
            f"(≤ {BUDGET[1]:.0f}): {'meets' if meets else 'does NOT meet'} the budget"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
