"""Per-step CPU time of the preview pipelines beside pink (daqp), immune to other processes.

Run: ``python benchmarks/bench_preview_cpu.py [--steps N] [--rounds R]``. The Panda pipelines of
``otmm-qp bench`` (:data:`otmm_qp.bench.pipelines.PREVIEWS` and ``pink (daqp)``) replay the same
recorded states, each in order (one untimed pass, then ``R`` rounds), timed with
``time.thread_time`` — the CPU time of this thread, so a step preempted by another process is
not charged for the wait. On a shared machine the wall-clock p99 of ``otmm-qp bench`` measures
the scheduler (a 4 ms time slice lands in 1–10 % of steps); this table's p99 is the step's own
worst case. Prints a Markdown table: median, p99 and max [µs], and the medians' and p99s'
ratios to pink (daqp).
"""

from __future__ import annotations

from otmm_qp.blas_threads import prefer_single_threaded_blas

prefer_single_threaded_blas()  # before NumPy loads: one BLAS thread, as the CLI runs

import argparse  # noqa: E402
import time  # noqa: E402
from collections.abc import Sequence  # noqa: E402

import numpy as np  # noqa: E402

from otmm_qp.bench.pipelines import PREVIEWS, REFERENCE, build_steps  # noqa: E402
from otmm_qp.bench.scenarios import panda_scenario  # noqa: E402


def cpu_times(steps: int, rounds: int) -> dict[str, np.ndarray]:
    """CPU time [µs] of every step, shape ``(rounds·steps,)``, per preview pipeline and pink."""
    scenario = panda_scenario(steps)
    wanted = [REFERENCE, *(label for label, _, _ in PREVIEWS)]
    built, _ = build_steps(scenario, True, only=wanted)
    clock, out = time.thread_time, {}
    for name in (n for n in wanted if n in built):
        run = built[name]
        for k in range(scenario.steps):
            run(k)
        samples = np.empty(rounds * scenario.steps)
        for i in range(samples.shape[0]):
            begin = clock()
            run(i % scenario.steps)
            samples[i] = clock() - begin
        out[name] = samples * 1e6
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Time the pipelines and print the table."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--steps", type=int, default=300, help="replayed states (default 300)")
    parser.add_argument("--rounds", type=int, default=3, help="rounds (default 3)")
    args = parser.parse_args(argv)
    times = cpu_times(args.steps, args.rounds)
    reference = times.get(REFERENCE)
    print("| pipeline | median µs | p99 µs | max µs | median × pink | p99 × pink |")
    print("|---|---|---|---|---|---|")
    for name, v in times.items():
        median, p99 = float(np.median(v)), float(np.percentile(v, 99))
        ratios = (
            (median / float(np.median(reference)), p99 / float(np.percentile(reference, 99)))
            if reference is not None
            else (float("nan"), float("nan"))
        )
        print(
            f"| {name} | {median:.0f} | {p99:.0f} | {v.max():.0f} | "
            f"{ratios[0]:.2f} | {ratios[1]:.2f} |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
