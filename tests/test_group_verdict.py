"""Per robot × generator verdicts: paired Holm outcomes and the Pareto front of medians."""

from __future__ import annotations

import numpy as np
import pytest

from otmm_qp.exceptions import OtmmError
from otmm_qp.studies.group_verdict import group_verdicts, pareto_front, render
from otmm_qp.studies.report import Rows

OBJECTIVES = ["rms_error", "max_joint_speed", "max_jump"]


def rows(values: dict[str, tuple[float, float, float]], tasks: int = 30, seed: int = 0) -> Rows:
    rng = np.random.default_rng(seed)
    out = []
    noise = rng.uniform(0.9, 1.1, size=(tasks, 3))
    for name, base in values.items():
        for t in range(tasks):
            row = {"robot": "r", "generator": "g", "task_index": t, "loop_mode": "clik",
                   "controller": name, "status": "ok"}  # fmt: skip
            for k, metric in enumerate(OBJECTIVES):
                row[metric] = base[k] * noise[t, k] * (1.0 + 0.01 * t)
            out.append(row)
    return Rows(out)


def test_pareto_front_of_medians() -> None:
    points = {
        "a": (1.0, 2.0, 3.0),
        "b": (2.0, 1.0, 3.0),
        "c": (2.0, 2.0, 3.0),
        "d": (1.0, 2.0, 3.0),
    }
    assert pareto_front(points) == ["a", "b", "d"]
    assert pareto_front({"x": (float("nan"), 1.0, 1.0), "y": (5.0, 5.0, 5.0)}) == ["y"]


def test_a_dominating_row_and_a_losing_one() -> None:
    data = rows({"ours": (1.0, 1.0, 1.0), "other": (2.0, 1.0, 3.0), "fast": (3.0, 0.5, 3.0)})
    (verdict,) = group_verdicts(data, "ours", OBJECTIVES)
    outcomes = [outcome for _, _, outcome in verdict.against_best]
    assert outcomes == ["better", "worse", "better"]  # 'fast' has the lower peak speed
    assert verdict.verdict == "loses on max_joint_speed"
    assert set(verdict.pareto) == {"ours", "fast"}
    (only,) = group_verdicts(
        rows({"ours": (1.0, 1.0, 1.0), "other": (2.0, 2.0, 2.0)}), "ours", OBJECTIVES
    )
    assert only.verdict == "dominates"
    text = render([verdict], "ours", OBJECTIVES)
    assert "loses on max_joint_speed" in text and "**front**" in text


def test_identical_rows_tie_and_an_unknown_name_is_refused() -> None:
    data = rows({"ours": (1.0, 1.0, 1.0), "twin": (1.0, 1.0, 1.0)})
    (verdict,) = group_verdicts(data, "ours", OBJECTIVES)
    assert verdict.verdict == "not worse"
    with pytest.raises(OtmmError, match="--ours: no controller 'nope'"):
        group_verdicts(data, "nope", OBJECTIVES)
