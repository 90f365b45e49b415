"""Per-step cost of otmm-qp pipelines against pink, mink and Drake (see :mod:`otmm_qp.bench`).

Run: ``python benchmarks/bench_step.py [--out DIR] [--steps N]`` (same as ``otmm-qp bench``);
writes ``bench.json`` and ``bench.md`` and prints the Markdown table.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from otmm_qp.bench import run_bench


def main() -> int:
    """Parse the arguments and run the benchmark."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/bench"))
    parser.add_argument("--steps", type=int, default=300)
    args = parser.parse_args()
    return run_bench(args.out, args.steps)


if __name__ == "__main__":
    raise SystemExit(main())
