"""``otmm-qp study plants DIR [--reference PLANT] [--pair NEW OLD] [--out FILE]``: headline.

Which strategies keep their ranking under a realistic plant; see
:mod:`otmm_qp.studies.plant_headline`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "the headline of a study with a plants axis: rankings per plant against a reference plant"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The study folder, ``--reference`` and ``--out``."""
    parser.add_argument("study", type=Path, help="the study folder")
    parser.add_argument(
        "--reference", default="ideal", help="the plant every other is compared with (ideal)"
    )
    parser.add_argument("--out", default=None, help="write the Markdown to this file")
    parser.add_argument(
        "--pair",
        nargs=2,
        action="append",
        metavar=("NEW", "OLD"),
        default=None,
        help="also compare two rows (controller@plant) on the same tasks: interface aborts, "
        "position limits, success (McNemar), max error (Wilcoxon); repeatable",
    )


def run(args: argparse.Namespace) -> int:
    """Print (or write) the headline table and verdict lines (and the limit-cost table)."""
    from otmm_qp.commands.text_output import emit, out_file
    from otmm_qp.studies.plant_headline import headline, limit_cost, pair_cost, plant_rows

    out = out_file(args.out)
    rows = plant_rows(args.study)
    text = headline(rows, args.reference).rstrip("\n")
    cost = limit_cost(rows)  # qp against qp-box (today's box), when the study has both
    pairs = [(new, old) for new, old in args.pair or ()]
    paired = pair_cost(rows, pairs) if pairs else ""
    text += "\n\n" + cost.rstrip("\n") if cost else ""
    emit(text + ("\n\n" + paired.rstrip("\n") if paired else ""), out)
    return 0
