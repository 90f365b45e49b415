"""Per-step cost of otmm-qp pipelines against pink, mink and Drake (see :mod:`otmm_qp.bench`).

Run: ``python benchmarks/bench_step.py [--out DIR] [--steps N] [--rounds R] [--planar-only]``
(``otmm-qp bench`` with the same defaults); writes ``bench.json`` and ``bench.md`` and prints
the Markdown tables.
"""

from __future__ import annotations

from otmm_qp.blas_threads import prefer_single_threaded_blas

prefer_single_threaded_blas()  # before NumPy loads: one BLAS thread, as the CLI runs

import argparse  # noqa: E402
from collections.abc import Sequence  # noqa: E402

from otmm_qp.bench import run_bench  # noqa: E402
from otmm_qp.commands.bench import add_arguments  # noqa: E402


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the arguments (those of ``otmm-qp bench``) and run the benchmark."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    add_arguments(parser)
    args = parser.parse_args(argv)
    return run_bench(args.out, args.steps, args.rounds, args.planar_only)


if __name__ == "__main__":
    raise SystemExit(main())
