"""``otmm-qp bench``: time one control step of each pipeline (see :mod:`otmm_qp.bench`)."""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "bench"
HELP = "time one control step of each pipeline"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``--out`` folder and ``--steps`` per pipeline."""
    parser.add_argument("--out", type=Path, default=Path("results/bench"))
    parser.add_argument("--steps", type=int, default=300)


def run(args: argparse.Namespace) -> int:
    """Run the benchmark."""
    from otmm_qp.bench import run_bench

    return run_bench(args.out, args.steps)
