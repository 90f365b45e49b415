"""The planar study's published numbers are what the shipped command produces.

The README summarises the study; the table and its sentences are in docs/study-results.md
("Measured: the planar study"), read from there (``SOURCE``).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from otmm_qp.cli import main

ROOT = Path(__file__).resolve().parents[2]
SOURCE = ROOT / "docs" / "study-results.md"  # where the planar study's numbers are published


def _readme_rows() -> dict[str, list[str]]:
    text = SOURCE.read_text(encoding="utf-8")
    section = text[text.index("otmm-qp study configs/studies/planar.yaml --workers 2") :]
    section = section[: section.index("\n\n", section.index("| controller |"))]
    rows = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip("|").split("|")]
        if len(cells) == 5 and cells[0] not in ("controller",) and not cells[0].startswith("-"):
            rows[cells[0]] = cells[1:]
    return rows


@pytest.mark.slow
def test_planar_study_table_in_readme_is_regenerated(tmp_path: Path, capsys) -> None:
    readme = _readme_rows()
    assert len(readme) == 5
    out = tmp_path / "planar-study"
    status = main(["study", str(ROOT / "configs/studies/planar.yaml"), "--out", str(out)]
                  + ["--workers", "1"])  # fmt: skip
    assert status == 0, capsys.readouterr().err
    report = (out / "study_report.md").read_text(encoding="utf-8")
    pooled = report[report.index("## All robots") :]
    pooled = pooled[: pooled.index("\n## ", 5)]
    for controller, (success, max_error, peak, jump) in readme.items():
        line = next(row for row in pooled.splitlines() if row.startswith(f"| {controller} |"))
        assert success in line, (controller, line)
        for value in (max_error, peak, jump):
            # The table shows the median; the report adds its bootstrap interval after it.
            assert re.search(rf"\| {re.escape(value)} \[", line), (controller, value, line)
    _check_reference_sentence(out)
    _check_paired_sentence(report)
    _check_graceful_sentence(pooled)


def _check_graceful_sentence(pooled: str) -> None:
    """How many unachievable tasks the graceful criteria pass, from the report's rates."""
    text = " ".join(SOURCE.read_text(encoding="utf-8").split())
    found = re.search(r"dls passes (\d+) of them, qp and OTMM\+pinv\[sigma_s=0\.05\] (\d+)\)", text)
    assert found, "the graceful sentence changed its form"

    def successes(controller: str) -> int:
        line = next(r for r in pooled.splitlines() if r.startswith(f"| {controller} |"))
        cells = [c.strip() for c in line.strip("|").split("|")]
        return round(int(cells[1]) * float(cells[3].split(" %")[0]) / 100)

    certified = (
        44  # the reference sentence's N, checked against the data by _check_reference_sentence
    )
    assert successes("dls") - certified == int(found.group(1))
    for name in ("qp", "OTMM+pinv[sigma_s=0.05]"):
        assert successes(name) - certified == int(found.group(2)), name


def _check_reference_sentence(out: Path) -> None:
    """The sentence "the reference certifies N of the M tasks", and who solves those."""
    from otmm_qp.studies.storage import read_episodes

    text = SOURCE.read_text(encoding="utf-8")
    found = re.search(r"the reference certifies (\d+)\s+of the (\d+) tasks", text)
    assert found is not None
    table = read_episodes(out)
    assert table is not None
    rows = table.to_pylist()
    oracle = {r["task_id"]: r for r in rows if r["controller"] == "oracle"}
    feasible = {t for t, r in oracle.items() if r["reference.status"] == "achievable"}
    assert (len(feasible), len(oracle)) == (int(found.group(1)), int(found.group(2)))
    others = {oracle[t]["generator"] for t in set(oracle) - feasible}
    assert others <= {"beyond_reach", "near_singular"}
    from otmm_qp.studies.rows import load_rows

    config, recomputed = load_rows(out)
    bound = config.success.max_position_error
    for name in ("dls", "qp", "OTMM+pinv[sigma_s=0.02]", "OTMM+pinv[sigma_s=0.05]"):
        solved = {r["task_id"] for r in rows if r["controller"] == name and r["success"]}
        assert solved & feasible == feasible, name  # every certified task
        within = {r["task_id"] for r in rows if r["controller"] == name and r["max_error"] <= bound}
        assert within & solved == feasible, name  # "meet the tolerance on exactly those 44"
    # The stored ``success`` column is the report's: judged with the task's reference.
    by_key = {r["episode_key"]: r["success"] for r in recomputed.rows}
    # (The report does not judge the oracle rows; theirs is the criteria applied to the path.)
    assert all(
        bool(r["success"]) == by_key[r["episode_key"]] for r in rows if r["controller"] != "oracle"
    )


def _check_paired_sentence(report: str) -> None:
    """The paired OTMM + pinv vs pinv counts and Holm p are the report's."""
    text = " ".join(SOURCE.read_text(encoding="utf-8").split())
    found = re.search(
        r"where both kept them, (\d+) of the 30 2-link tasks, OTMM \+ pinv has a strictly lower "
        r"oracle-relative max error than pinv on (\d+)–(\d+) of them "
        r"\(tied on (\d+)–(\d+), higher on (\d+)–(\d+)\); no Wilcoxon test separates the "
        r"two \(Holm p ≥ ([0-9.]+)\)",
        text,
    )
    assert found, "the paired sentence changed its form"
    lower, ties, higher, holm = (
        sorted(map(int, found.group(2, 3))),
        sorted(map(int, found.group(4, 5))),
        sorted(map(int, found.group(6, 7))),
        float(found.group(8)),
    )
    table = report[report.index("### Paired comparisons on planar2: oracle_relative_error") :]
    table = table[: table.index("\n###")]
    rows = [
        [c.strip() for c in line.strip("|").split("|")]
        for line in table.splitlines()
        if line.startswith("| OTMM+pinv") and "| pinv |" in line
    ]
    assert len(rows) == 2
    assert sorted(int(r[3]) for r in rows) == lower
    assert sorted(int(r[4]) for r in rows) == ties
    assert sorted(int(r[5]) for r in rows) == higher
    assert all(r[2] == found.group(1) for r in rows)  # the tasks where both kept the limits
    assert min(float(r[9]) for r in rows) == holm
    assert all(float(r[9]) > 0.05 for r in rows)  # not separated
