"""``otmm-qp report DIR``: write report.html and report.md for a results folder."""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "report"
HELP = "write report.html and report.md for a results folder"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The results folder."""
    parser.add_argument("results", type=Path)


def run(args: argparse.Namespace) -> int:
    """Write the report (a study report when the folder holds a study dataset)."""
    from otmm_qp.output.report import write_any_report

    html, markdown = write_any_report(args.results)
    print(f"report: {html}\n        {markdown}")
    return 0
