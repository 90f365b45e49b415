"""Study statistics against scipy and hand-computed cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from otmm_qp.studies.statistics import (
    binned_medians,
    bootstrap_median,
    holm,
    paired_comparisons,
    paired_test,
    rank_with_ties,
    wilson_interval,
)


@pytest.mark.parametrize(("k", "n"), [(0, 10), (3, 10), (10, 10), (57, 200), (1, 1)])
def test_wilson_matches_scipy(k: int, n: int) -> None:
    expected = stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    low, high = wilson_interval(k, n)
    assert low == pytest.approx(expected.low, abs=1e-12)
    assert high == pytest.approx(expected.high, abs=1e-12)


def test_wilson_no_trials_is_uninformative() -> None:
    assert wilson_interval(0, 0) == (0.0, 1.0)


def test_bootstrap_median_is_seeded_and_covers_like_scipy() -> None:
    rng = np.random.default_rng(4)
    data = rng.lognormal(size=300)
    median, low, high = bootstrap_median(data, seed=1)
    assert median == pytest.approx(float(np.median(data)))
    assert (median, low, high) == bootstrap_median(data, seed=1)
    reference = stats.bootstrap(
        (data,), np.median, method="percentile", n_resamples=4000, random_state=2
    ).confidence_interval
    assert low == pytest.approx(reference.low, rel=0.05)
    assert high == pytest.approx(reference.high, rel=0.05)
    assert low <= median <= high


def test_bootstrap_ignores_nan_and_handles_empty() -> None:
    assert bootstrap_median(np.array([1.0, np.nan, 3.0, 2.0]), resamples=200)[0] == 2.0
    assert all(math.isnan(v) for v in bootstrap_median(np.array([np.nan])))


def test_holm_known_case() -> None:
    # sorted p: 0.01 (x3), 0.02 (x2 -> 0.04), 0.04 (x1 -> 0.04)
    assert holm([0.04, 0.01, 0.02]) == pytest.approx([0.04, 0.03, 0.04])
    assert holm([0.5, 0.9]) == pytest.approx([1.0, 1.0])


def test_paired_test_matches_scipy_wilcoxon_and_counts_wins() -> None:
    rng = np.random.default_rng(0)
    a = rng.normal(size=40)
    b = a + 0.3 + 0.2 * rng.normal(size=40)
    result = paired_test("a", "b", a, b)
    assert result.p_value == pytest.approx(stats.wilcoxon(a, b).pvalue)
    assert result.win_rate == pytest.approx(np.mean(a < b))
    ties = paired_test("a", "b", np.array([1.0, 2.0, 3.0]), np.array([1.0, 2.0, 3.0]))
    assert ties.win_rate == 0.5 and ties.p_value == 1.0


def test_paired_comparisons_use_common_tasks_and_holm() -> None:
    values = {
        "x": {1: 1.0, 2: 2.0, 3: 3.0, 4: 4.0, 5: 5.0, 6: 6.0, 7: 7.0},
        "y": {1: 2.0, 2: 3.0, 3: 4.5, 4: 5.0, 5: 6.5, 6: 7.0, 7: 8.0, 99: 0.0},
        "z": {1: 1.0, 2: 2.0, 3: 3.0, 4: 4.0, 5: 5.0, 6: 6.0, 7: 7.0},
    }
    results = {(r.a, r.b): r for r in paired_comparisons(values)}
    assert results[("x", "y")].pairs == 7
    assert results[("x", "y")].win_rate == 1.0
    raw = [r.p_value for r in results.values()]
    assert [r.p_holm for r in results.values()] == pytest.approx(holm(raw))


def test_ranking_ties_overlapping_intervals() -> None:
    intervals = {"a": (1.0, 0.9, 1.1), "b": (1.05, 0.95, 1.2), "c": (2.0, 1.8, 2.2)}
    ranking = rank_with_ties(intervals)
    assert ranking == [("a", 1, True), ("b", 1, True), ("c", 3, False)]
    rates = {"a": (0.9, 0.85, 0.95), "b": (0.5, 0.4, 0.6)}
    assert rank_with_ties(rates, higher_is_better=True) == [("a", 1, False), ("b", 2, False)]


def test_binned_medians() -> None:
    x = np.array([0.001, 0.002, 0.01, 0.02, 0.1, 0.2])
    y = np.array([10.0, 20.0, 3.0, 5.0, 1.0, 1.0])
    centres, medians, counts = binned_medians(x, y, np.array([0.001, 0.005, 0.05, 0.2]))
    assert counts.tolist() == [2, 2, 2]
    assert medians.tolist() == [15.0, 4.0, 1.0]
    assert centres[0] == pytest.approx(math.sqrt(0.001 * 0.005))


def test_bootstrap_interval_does_not_depend_on_row_order() -> None:
    """Serial and Dask studies store the same episodes in different orders: same report."""
    values = np.random.default_rng(5).lognormal(size=301)
    shuffled = np.random.default_rng(6).permutation(values)
    assert bootstrap_median(values, seed=0) == bootstrap_median(shuffled, seed=0)
