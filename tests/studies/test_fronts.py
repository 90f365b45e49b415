"""Pareto fronts of study groups (studies/fronts.py): the front, the criterion, the report."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from otmm_qp.exceptions import ConfigError
from otmm_qp.metrics.table import STUDY_MEDIANS, STUDY_OBJECTIVES, STUDY_PAIRED, metric
from otmm_qp.output.markdown import table_markdown
from otmm_qp.output.pareto import dominates
from otmm_qp.studies.criteria import RATIO_COLUMNS
from otmm_qp.studies.fronts import FAMILIES, front_of, group_fronts, summary_table
from otmm_qp.studies.group_verdict import render
from otmm_qp.studies.rows import Rows
from otmm_qp.studies.statistics import exact_signed_rank_p, wilcoxon_p
from otmm_qp.studies.verdicts import check_highlight

OBJECTIVES = ["max_error", "max_joint_speed", "max_jump"]


def _key(row: dict[str, object]) -> object:
    return row["task_index"]


def rows(values: dict[str, tuple[float, float, float]], tasks: int = 30, seed: int = 0) -> list:
    """Rows whose metrics are ``base · noise · (1 + 0.01 t)``: paired, distinct per row."""
    rng = np.random.default_rng(seed)
    out = []
    noise = rng.uniform(0.9, 1.1, size=(tasks, 3))
    for name, base in values.items():
        for t in range(tasks):
            row = {"robot": "r", "generator": "g", "task_index": t, "loop_mode": "clik",
                   "controller": name, "status": "ok"}  # fmt: skip
            for k, name_k in enumerate(OBJECTIVES):
                row[name_k] = base[k] * noise[t, k] * (1.0 + 0.01 * t)
            out.append(row)
    return out


def test_front_dominated_rows_and_the_criterion() -> None:
    data = rows({"ours": (1.0, 1.0, 1.0), "other": (2.0, 1.0, 3.0), "fast": (3.0, 0.5, 3.0)})
    data += [{**r, "controller": "oracle"} for r in data[:30]]  # never a competitor
    (front,) = group_fronts(data, OBJECTIVES, _key, 50)
    assert front.tasks == 30 and [r.name for r in front.rows] == ["ours", "other", "fast"]
    assert front.front == ("ours", "fast")
    other = front.row("other")
    assert other is not None and other.dominated_by == ("ours",) and not other.on_front
    ours = front.row("ours")
    assert ours is not None
    assert [c.other for c in ours.comparisons] == ["other", "fast", "other"]
    for family in FAMILIES:
        assert ours.outcomes(family) == ("better", "worse", "better")
        assert not ours.meets(family) and ours.verdict(family) == "loses on max_joint_speed"
    assert front.best_on_all is None and front.meeting() == ()
    (alone,) = group_fronts(
        rows({"ours": (1.0, 1.0, 1.0), "b": (2.0, 2.0, 2.0)}), OBJECTIVES, _key, 50
    )
    assert alone.meeting() == ("ours",) and alone.best_on_all == "ours"
    assert alone.row("ours").verdict() == "dominates"  # type: ignore[union-attr]
    text = "\n".join(table_markdown(summary_table([front], lambda n: n == "ours")))
    assert "**ours** (ours)" in text and "loses on max_joint_speed" in text


def test_twins_tie_errors_are_missing_and_objectives_must_be_costs() -> None:
    data = rows({"ours": (1.0, 1.0, 1.0), "twin": (1.0, 1.0, 1.0)})
    data[0] = {**data[0], "status": "error"}  # a run error is a missing value, not a pair
    data[30] = {**data[30], "status": "error"}
    front = front_of("r", "g", data, OBJECTIVES, _key, resamples=50)
    ours = front.row("ours")
    assert ours is not None and ours.outcomes() == ("tie", "tie", "tie")
    assert ours.comparisons[0].result.pairs == 29
    assert ours.verdict() == "not worse" and front.front == ("ours", "twin")
    with pytest.raises(ConfigError, match="'min_sigma' is not a lower-is-better metric"):
        front_of("r", "g", data, ["min_sigma"], _key)


@settings(max_examples=15, deadline=None)
@given(
    st.lists(
        st.tuples(*(st.floats(0.0, 10.0) for _ in range(3))), min_size=2, max_size=6, unique=True
    ),
    st.integers(0, 2**16),
)
def test_front_invariants_and_holm_families(bases: list, seed: int) -> None:
    names = [f"c{i}" for i in range(len(bases))]
    front = front_of(
        "r", "g", rows(dict(zip(names, bases, strict=True)), 12, seed), OBJECTIVES, _key, 20
    )
    on = [r for r in front.rows if r.on_front]
    assert on  # finite medians always leave a front
    for a in on:
        assert not any(dominates(b.medians, a.medians) for b in front.rows if b is not a)
    for r in front.rows:
        if not r.on_front:  # each dominated row names front rows that dominate it
            assert r.dominated_by and all(
                dominates(front.row(n).medians, r.medians)  # type: ignore[union-attr]
                for n in r.dominated_by
            )
        for c in r.comparisons:  # Holm over a sub-family never adjusts a p upwards
            assert c.p_holm["best"] <= c.p_holm["all"] + 1e-15
            assert c.result.p_value <= c.p_holm["best"] + 1e-15


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(-3, 3), min_size=1, max_size=9), st.booleans())
def test_exact_signed_rank_p_is_scipys(values: list[int], halves: bool) -> None:
    d = np.array(values, dtype=float) * (0.5 if halves else 1.0)
    if not np.any(d != 0.0):
        assert wilcoxon_p(d, np.zeros_like(d)) == 1.0
        return
    expected = float(stats.wilcoxon(d, zero_method="wilcox").pvalue)
    assert exact_signed_rank_p(d) == pytest.approx(expected, rel=1e-12)
    assert wilcoxon_p(d, np.zeros_like(d)) == pytest.approx(expected, rel=1e-12)
    assert math.isnan(wilcoxon_p(np.array([math.nan]), np.array([1.0])))


def test_the_study_lists_are_rows_of_the_metric_table() -> None:
    for name in (*STUDY_MEDIANS, *STUDY_PAIRED, *STUDY_OBJECTIVES, *RATIO_COLUMNS):
        assert metric(name).name == name
    assert all(metric(n).lower_is_better for n in (*STUDY_OBJECTIVES, "oracle_relative_error"))
    assert metric("max_speed_ratio").heading == "peak |q̇_j|/q̇_max,j"


def test_highlight_must_name_a_controller() -> None:
    data = Rows(rows({"ours": (1.0, 1.0, 1.0), "b": (2.0, 2.0, 2.0)}))
    check_highlight(data, "ours")
    check_highlight(data, None)
    with pytest.raises(
        ConfigError, match=r"--highlight: no controller 'x' in the study; have: ours, b"
    ):
        check_highlight(data, "x")
    fronts = group_fronts(data.rows, OBJECTIVES, _key, 50)
    assert "ours: on the front in 1 of 1, meets the criterion in 1" in render(fronts, "ours")
