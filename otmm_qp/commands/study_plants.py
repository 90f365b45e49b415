"""``otmm-qp study plants DIR [--reference PLANT] [--out FILE]``: a plants study's headline.

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


def run(args: argparse.Namespace) -> int:
    """Print (or write) the headline table and verdict lines (and the limit-cost table)."""
    from otmm_qp.commands.text_output import emit, out_file
    from otmm_qp.studies.plant_headline import headline, limit_cost, plant_rows

    out = out_file(args.out)
    rows = plant_rows(args.study)
    text = headline(rows, args.reference).rstrip("\n")
    cost = limit_cost(rows)  # qp against qp-box (today's box), when the study has both
    emit(text + ("\n\n" + cost.rstrip("\n") if cost else ""), out)
    return 0
