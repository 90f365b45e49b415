r"""Regenerate, or check, the docs table that comes from a stored study.

"Which strategy for which task" in ``docs/strategies.md`` (the table the README links) is what
``otmm-qp study verdict DIR --ours sigma_lm --kinds`` prints for the study
``configs/studies/strategies_readme.yaml``. A copy of that study's rows (``study.json`` and
``episodes/``, about 0.4 MB) is kept in ``tests/data/strategies_readme``, so the suite checks
the doc against the rows in seconds instead of re-running the 616 episodes. Usage::

    # the whole claim, from scratch (about 80 s on 2 cores), then the doc and the stored copy:
    otmm-qp study configs/studies/strategies_readme.yaml --out results/strategies-readme \
        --highlight sigma_lm
    python tools/doc_tables.py --study results/strategies-readme --store
    # what the suite runs: the doc's table against the stored rows (exit 1 when it differs)
    python tools/doc_tables.py --check

``--check`` also fails when the stored rows are not the current study file's (its config hashes
to another study id: the file changed since the rows were stored), naming the command above.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

from otmm_qp.cli import main as otmm_qp
from otmm_qp.paths import atomic_write_text
from otmm_qp.studies.spec import load_study
from otmm_qp.studies.storage import study_id

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "configs" / "studies" / "strategies_readme.yaml"
STORED = ROOT / "tests" / "data" / "strategies_readme"
DOC = ROOT / "docs" / "strategies.md"
SECTION = "\n## Which strategy for which task\n"
HEADER = "| task kind (tasks) |"
OURS = "sigma_lm"
REGENERATE = (
    "otmm-qp study configs/studies/strategies_readme.yaml --out results/strategies-readme "
    "--highlight sigma_lm && python tools/doc_tables.py --study results/strategies-readme --store"
)


def table_span(text: str) -> tuple[int, int]:
    """Offsets of the doc's table in ``text``.

    Returns:
        Start and end of the first table (``HEADER`` to the next blank line) after the section
        heading ``SECTION``.
    """
    section = text.index(SECTION)
    start = text.index(HEADER, section)
    end = text.find("\n\n", start)
    return start, len(text) if end < 0 else end + 1


def rendered_table(study: Path) -> str:
    """The table ``otmm-qp study verdict STUDY --ours sigma_lm --kinds`` prints.

    Returns:
        Its lines from ``HEADER`` to the first blank line, newline-terminated.
    """
    with tempfile.TemporaryDirectory() as scratch:
        printed = Path(scratch) / "kinds.md"
        argv = ["study", "verdict", str(study), "--ours", OURS, "--kinds", "--out", str(printed)]
        if otmm_qp(argv) != 0:
            raise SystemExit(f"doc_tables: otmm-qp {' '.join(argv[:6])} failed")
        text = printed.read_text(encoding="utf-8")
    start = text.index(HEADER)
    end = text.find("\n\n", start)
    return text[start : len(text) if end < 0 else end + 1]


def stale(study: Path, config: Path) -> str | None:
    """Why ``study``'s rows are not ``config``'s (its study id differs), or None."""
    stored = json.loads((study / "study.json").read_text(encoding="utf-8"))["study_id"]
    current = study_id(load_study(config).model_dump(mode="json"))
    if stored == current:
        return None
    return f"{study} holds study {stored}, {config.name} is now {current}: rerun {REGENERATE}"


def store(study: Path, into: Path) -> None:
    """Copy ``study``'s ``study.json`` and ``episodes/`` to ``into`` (replacing its copy)."""
    if into.exists():
        shutil.rmtree(into)
    (into / "episodes").mkdir(parents=True)
    shutil.copy2(study / "study.json", into / "study.json")
    for part in sorted((study / "episodes").glob("*.parquet")):
        shutil.copy2(part, into / "episodes" / part.name)


def main(argv: Sequence[str] | None = None) -> int:
    """Rewrite the doc's table from ``--study`` (or, with ``--check``, compare); 0 when equal."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", type=Path, default=STORED, help="the study folder to read")
    parser.add_argument("--config", type=Path, default=CONFIG, help="the study file it ran")
    parser.add_argument("--doc", type=Path, default=DOC, help="the Markdown file to rewrite")
    parser.add_argument("--store", action="store_true", help=f"copy the rows to {STORED}")
    parser.add_argument("--check", action="store_true", help="compare only; exit 1 on a diff")
    args = parser.parse_args(argv)
    reason = stale(args.study, args.config)
    if reason is not None:
        print(f"doc_tables: {reason}", file=sys.stderr)
        return 1
    table = rendered_table(args.study)
    text = args.doc.read_text(encoding="utf-8")
    start, end = table_span(text)
    if args.check:
        if text[start:end] == table:
            return 0
        old, new = text[start:end].splitlines(), table.splitlines()
        pairs = enumerate(zip(old, new, strict=False))
        first = next((i for i, (a, b) in pairs if a != b), min(len(old), len(new)))
        print(
            f"doc_tables: {args.doc.name}'s table differs from {args.study} at its line "
            f"{first + 1}; regenerate with: python tools/doc_tables.py --study {args.study}",
            file=sys.stderr,
        )
        return 1
    if args.store and args.study.resolve() != STORED.resolve():
        store(args.study, STORED)
    atomic_write_text(args.doc, text[:start] + table + text[end:])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
