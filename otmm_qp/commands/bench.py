"""``otmm-qp bench``: time one control step of each pipeline (see :mod:`otmm_qp.bench`)."""

from __future__ import annotations

import argparse

NAME = "bench"
HELP = "time one control step of each pipeline"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``--out``, ``--steps``, ``--rounds`` and ``--planar-only``.

    ``benchmarks/bench_step.py`` uses the same options, so both accept the command line that
    ``bench.json`` records.
    """
    from otmm_qp.bench.run import ROUNDS

    parser.add_argument(
        "--out", default="results/bench", help="bench folder (default: results/bench)"
    )
    parser.add_argument("--steps", type=int, default=300, help="replayed states per scenario")
    parser.add_argument(
        "--rounds", type=int, default=ROUNDS,
        help=f"interleaved timing rounds (default {ROUNDS}; more rounds, steadier medians)",
    )  # fmt: skip
    parser.add_argument("--planar-only", action="store_true", help="skip the Panda scenario")


def run(args: argparse.Namespace) -> int:
    """Run the benchmark."""
    from otmm_qp.bench import run_bench
    from otmm_qp.output.folders import check_out_argument

    return run_bench(check_out_argument(args.out), args.steps, args.rounds, args.planar_only)
