"""``otmm-qp report DIR``: write report.html and report.md for a results folder."""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "report"
HELP = "write report.html and report.md for a results folder"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The results folder."""
    parser.add_argument("results", type=Path)
    parser.add_argument(
        "--replay", action="store_true", help="also write replays (see 'otmm-qp replay')"
    )


def run(args: argparse.Namespace) -> int:
    """Write the report (a study report when the folder holds a study dataset)."""
    from otmm_qp.output.report import write_any_report

    replay_error = None
    if args.replay:
        from otmm_qp.replay.write import replay_after_run

        replay_error = replay_after_run(args.results)
    html, markdown = write_any_report(args.results)
    print(f"report: {html}\n        {markdown}")
    if replay_error is not None:
        raise replay_error
    return 0
