"""``otmm-qp study tradeoff DIR``: is the trade-off the task's or the strategies'?

The offline optimum under the calm row's per-task peak speed against the accurate row; see
:mod:`otmm_qp.studies.tradeoff`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "the offline optimum under the calm row's speeds against the accurate row"


def _tasks(text: str) -> int:
    from otmm_qp.exceptions import ConfigError

    try:
        value = int(text)
    except ValueError:
        raise ConfigError("--tasks", f"must be an integer >= 1, got {text!r:.40}") from None
    if value < 1:
        raise ConfigError("--tasks", f"must be an integer >= 1, got {value}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The study folder, ``--group-by``, ``--calm``, ``--accurate``, ``--tasks``, ``--out``."""
    parser.add_argument("study", type=Path, help="the study folder")
    parser.add_argument("--group-by", default="generator", help="generator or kind")
    parser.add_argument("--calm", default=None, help="the calm row (default: the front's)")
    parser.add_argument("--accurate", default=None, help="the accurate row (default: the front's)")
    parser.add_argument("--tasks", default=None, help="at most N tasks per group")
    parser.add_argument("--out", default=None, help="write the Markdown to this file")


def run(args: argparse.Namespace) -> int:
    """Print (or write) the Markdown of :func:`~otmm_qp.studies.tradeoff.study_tradeoff`."""
    from otmm_qp.commands.text_output import emit, out_file
    from otmm_qp.exceptions import ConfigError
    from otmm_qp.studies.rows import load_rows
    from otmm_qp.studies.tradeoff import GROUPINGS, render, resolution, study_tradeoff

    if args.group_by not in GROUPINGS:
        raise ConfigError(
            "--group-by", f"{args.group_by!r:.40} is not one of {', '.join(GROUPINGS)}"
        )
    tasks = None if args.tasks is None else _tasks(args.tasks)
    out = out_file(args.out)
    config, rows = load_rows(args.study)
    groups = study_tradeoff(config, rows, args.group_by, args.calm, args.accurate, tasks)
    emit(render(groups, resolution(config)), out)
    return 0
