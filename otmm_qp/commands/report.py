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
    parser.add_argument(
        "--highlight",
        help="study reports: a controller placed as 'ours' on each group's Pareto front",
    )


def write_any_report(results_dir: Path, highlight: str | None = None) -> tuple[Path, Path]:
    """The report of a results folder: a study report when it holds ``study.json``.

    ``highlight`` (study reports only) names the controller placed as *ours* on the fronts.

    The dispatch on the folder kind lives here, above both report modules, so the run report
    (``output/report.py``) and the study report (``studies/report/``) never import each
    other.
    """
    results_dir = Path(results_dir)
    if _is_study(results_dir):
        from otmm_qp.studies.report import write_study_report
        from otmm_qp.studies.storage import writing_report

        with writing_report(results_dir):
            html, markdown = write_study_report(results_dir, highlight)
        return Path(html), Path(markdown)
    if highlight is not None:
        from otmm_qp.exceptions import ConfigError

        raise ConfigError("--highlight", "only a study folder (with study.json) has fronts")
    from otmm_qp.output.report import write_report

    return write_report(results_dir)


def _is_study(results_dir: Path) -> bool:
    return (results_dir / "study.json").is_file() or (results_dir / "study.json").is_symlink()


def run(args: argparse.Namespace) -> int:
    """Write the report (a study report when the folder holds a study dataset)."""
    replay_error = None
    if args.highlight is not None and not _is_study(Path(args.results)):
        from otmm_qp.exceptions import ConfigError

        raise ConfigError("--highlight", "only a study folder (with study.json) has fronts")
    if args.replay:
        from otmm_qp.replay.write import replay_after_run

        replay_error = replay_after_run(args.results)
    html, markdown = write_any_report(args.results, args.highlight)
    print(f"report: {html}\n        {markdown}")
    if replay_error is not None:
        raise replay_error
    return 0
