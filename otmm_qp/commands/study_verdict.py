"""``otmm-qp study verdict DIR --ours NAME [--kinds] [--limit-keeping] [--out FILE]``.

Where the controller ``--ours`` sits on a study's Pareto fronts, per robot × generator or per
kind of task (``--kinds``); see :mod:`otmm_qp.studies.group_verdict`. ``--limit-keeping``:
against the rows that keep the arm's limits only — every other row that breaks them
(:mod:`otmm_qp.studies.limit_keeping`: a speed or position-limit failure) on any task of the
study is left out, and named.
"""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "where one controller sits on a study's Pareto fronts (per group or --kinds)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The study folder, ``--ours``, ``--kinds`` and ``--out``."""
    parser.add_argument("study", type=Path, help="the study folder")
    parser.add_argument("--ours", required=True, help="the controller placed on the fronts")
    parser.add_argument("--kinds", action="store_true", help="group by kind of task")
    parser.add_argument(
        "--limit-keeping",
        action="store_true",
        help="compare with the rows that keep the arm's limits on every task only",
    )
    parser.add_argument("--out", default=None, help="write the Markdown to this file")


def run(args: argparse.Namespace) -> int:
    """Print (or write) the fronts with ``--ours`` placed on them."""
    from otmm_qp.commands.text_output import emit, out_file
    from otmm_qp.studies.decide import GUARANTEE, judge_rows
    from otmm_qp.studies.group_verdict import kind_fronts, kind_rows, render
    from otmm_qp.studies.limit_keeping import limit_breaks
    from otmm_qp.studies.rows import Rows, load_rows
    from otmm_qp.studies.verdicts import check_highlight, study_fronts

    out = out_file(args.out)
    rows = load_rows(args.study)[1]
    check_highlight(rows, args.ours, "--ours")
    dropped: list[str] = []
    if args.limit_keeping:
        for name in rows.controllers():
            broken, total = limit_breaks(rows.rows, name)
            if broken and name != args.ours:
                dropped.append(f"{name} (limits broken on {broken} of {total} tasks)")
        gone = {entry.split(" (")[0] for entry in dropped}
        rows = Rows([r for r in rows.rows if r["controller"] not in gone])
    fronts = kind_fronts(rows) if args.kinds else study_fronts(rows)
    arm = judge_rows(rows.rows, 0, 0)  # the decision decision.md and the report open with
    head = [f"- {arm.arm_line(robot)}" for robot in rows.robots() if robot in arm.arms]
    text = render(fronts, args.ours, args.kinds, kind_rows(rows) if args.kinds else None)
    if args.limit_keeping:
        left = "; ".join(dropped) or "none"
        text = f"Limit-keeping rows only; left out: {left}.\n\n{text}"
    emit("\n".join(["Decision for the arm:", "", *head, "", GUARANTEE, "", text]), out)
    return 0
