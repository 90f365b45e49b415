"""``benchmarks/profile_reference.py`` runs a small study and charges the reference's phases.

A planar study of a few tasks (two beyond the reach, so the least squares and the polish run):
the table names the reference and its phases, which together are no longer than the
reference; Clarabel's solves fit in the polishes that call them; the reference is shorter
than the study's compute, and the floor the cone programs set is a share between 0 and 100 %.
Timings themselves are not asserted.
"""

from __future__ import annotations

import re
from pathlib import Path

import yaml

from tests.factories import reference_study, run_script


def test_profile_reference_charges_the_phases(tmp_path: Path) -> None:
    study = reference_study(
        "profile",
        seed=3,
        chunk_size=2,
        generators=[{"type": "beyond_reach", "count": 2, "duration": [0.6, 0.8]}],
    )
    config = tmp_path / "study.yaml"
    config.write_text(yaml.safe_dump(study, sort_keys=False), encoding="utf-8")
    done = run_script(
        "benchmarks/profile_reference.py", "--config", str(config), "--tasks", "0", timeout=120
    )
    assert done.returncode == 0, done.stderr
    rows = dict(re.findall(r"^\| ([^|]+?) \| ([0-9.]+) \| [0-9.]+ \|$", done.stdout, re.M))
    compute = float(re.search(r"study compute ([0-9.]+) s", done.stdout).group(1))  # type: ignore[union-attr]
    reference = float(rows["reference (solve_reference)"])
    assert 0.0 < reference < compute
    phases = ("lower_bound", "_starts", "_least_squares", "_polish", "summarise")
    for phase in phases:
        assert 0.0 <= float(rows[phase]) <= reference, phase
    # the phases run one after the other inside the reference (3-decimal rounding aside)
    assert sum(float(rows[phase]) for phase in phases) <= reference + 0.0005 * len(phases)
    assert float(rows["_polish"]) > 0.0  # beyond the reach: the cone polish ran
    assert float(rows["  Clarabel solve"]) <= float(rows["_polish"]) + float(
        rows.get("_position_optimum", 0.0)
    )
    floor = float(re.search(r"= ([0-9.]+) %$", done.stdout, re.M).group(1))  # type: ignore[union-attr]
    assert 0.0 <= floor < 100.0
