"""``otmm-qp study report DIR [--highlight NAME]``: (re)write a study folder's report."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "write study_report.html/.md (and figures) of a study folder"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The study folder and ``--highlight``."""
    parser.add_argument("study", type=Path, help="the study folder")
    parser.add_argument(
        "--highlight", help="a controller placed as 'ours' on each group's Pareto front"
    )


def run(args: argparse.Namespace) -> int:
    """Write the report; a folder without ``study.json`` is one line, exit 2."""
    from otmm_qp.studies.report import write_study_report
    from otmm_qp.studies.storage import writing_report

    with writing_report(args.study):
        html, markdown = write_study_report(args.study, args.highlight)
    print(f"report: {html}\n        {markdown}")
    return 0
