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


def write_any_report(results_dir: Path) -> tuple[Path, Path]:
    """The report of a results folder: a study report when it holds ``study.json``.

    The dispatch on the folder kind lives here, above both report modules, so the run report
    (``output/report.py``) and the study report (``studies/report.py``) never import each
    other.
    """
    results_dir = Path(results_dir)
    if (results_dir / "study.json").is_file() or (results_dir / "study.json").is_symlink():
        from otmm_qp.studies.report import write_study_report
        from otmm_qp.studies.storage import writing_report

        with writing_report(results_dir):
            html, markdown = write_study_report(results_dir)
        return Path(html), Path(markdown)
    from otmm_qp.output.report import write_report

    return write_report(results_dir)


def run(args: argparse.Namespace) -> int:
    """Write the report (a study report when the folder holds a study dataset)."""
    replay_error = None
    if args.replay:
        from otmm_qp.replay.write import replay_after_run

        replay_error = replay_after_run(args.results)
    html, markdown = write_any_report(args.results)
    print(f"report: {html}\n        {markdown}")
    if replay_error is not None:
        raise replay_error
    return 0
