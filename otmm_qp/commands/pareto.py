"""``otmm-qp pareto RESULTS... --out DIR``: the Pareto comparison of run folders.

Writes ``DIR/pareto.md`` and ``DIR/pareto.png`` (see :mod:`otmm_qp.output.pareto`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "pareto"
HELP = "Pareto comparison (error, peak speed, jump) of run folders: pareto.md and pareto.png"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The results folders and ``--out``."""
    parser.add_argument("results", nargs="+", type=Path, help="results folders (summary.csv)")
    parser.add_argument("--out", required=True, help="folder for pareto.md/.png")


def run(args: argparse.Namespace) -> int:
    """Write the comparison; a folder without ``summary.csv`` is one line, exit 2."""
    from otmm_qp.output.folders import check_out_argument
    from otmm_qp.output.pareto import write_pareto

    markdown, png = write_pareto(args.results, check_out_argument(args.out))
    print(f"  pareto: {markdown}\n  figure: {png}")
    return 0
