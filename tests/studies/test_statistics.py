"""Study statistics against scipy and hand-computed cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy import stats

from otmm_qp.studies.statistics import (
    binned_medians,
    bootstrap_interval,
    bootstrap_median,
    holm,
    mcnemar_exact,
    paired_comparisons,
    paired_ranking,
    paired_success,
    paired_test,
    rank_with_ties,
    significant_digits,
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


def test_paired_test_matches_scipy_wilcoxon_and_counts_strictly() -> None:
    rng = np.random.default_rng(0)
    a = rng.normal(size=40)
    b = a + 0.3 + 0.2 * rng.normal(size=40)
    result = paired_test("a", "b", a, b)
    assert result.p_value == pytest.approx(stats.wilcoxon(a, b).pvalue)
    assert result.lower == int(np.sum(a < b)) and result.ties == 0
    assert result.favoured == "a" and result.consistent
    ties = paired_test("a", "b", np.array([1.0, 2.0, 3.0]), np.array([1.0, 2.0, 3.0]))
    assert (ties.lower, ties.ties, ties.higher) == (0, 3, 0)
    assert ties.p_value == 1.0 and ties.favoured is None


def test_paired_comparisons_use_common_tasks_and_holm() -> None:
    values = {
        "x": {1: 1.0, 2: 2.0, 3: 3.0, 4: 4.0, 5: 5.0, 6: 6.0, 7: 7.0},
        "y": {1: 2.0, 2: 3.0, 3: 4.5, 4: 5.0, 5: 6.5, 6: 7.0, 7: 8.0, 99: 0.0},
        "z": {1: 1.0, 2: 2.0, 3: 3.0, 4: 4.0, 5: 5.0, 6: 6.0, 7: 7.0},
    }
    results = {(r.a, r.b): r for r in paired_comparisons(values)}
    assert results[("x", "y")].pairs == 7
    assert results[("x", "y")].lower == 7 and results[("x", "y")].favoured == "x"
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


# ------------------------------------------------------------ property tests (hypothesis)
_values = st.lists(
    st.sampled_from([0.0, 0.5, 1.0, 1.5, 2.0, 3.0])
    | st.floats(-5.0, 5.0, allow_nan=False, allow_subnormal=False),
    min_size=1,
    max_size=40,
)


@st.composite
def _paired(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray]:
    """Paired samples with many ties and zero differences (a grid) or continuous values."""
    a = np.array(draw(_values), dtype=float)
    shift = draw(st.sampled_from([0.0, 0.5, -0.5, 1.0]))
    noise = np.array(
        draw(
            st.lists(st.sampled_from([0.0, 0.0, 0.5, -0.5, 1.0]), min_size=a.size, max_size=a.size)
        )
    )
    return a, a + shift + noise


def _brute_rank_sums(d: np.ndarray) -> tuple[float, float]:
    """W⁻, W⁺ by the definition: average rank of |d_i| among the non-zero |d|, counted by hand."""
    nonzero = [x for x in d.tolist() if x != 0.0]
    w_minus = w_plus = 0.0
    for x in nonzero:
        below = sum(1 for y in nonzero if abs(y) < abs(x))
        equal = sum(1 for y in nonzero if abs(y) == abs(x))
        rank = below + (equal + 1) / 2.0
        if x < 0:
            w_minus += rank
        else:
            w_plus += rank
    return w_minus, w_plus


@given(_paired())
def test_paired_test_against_scipy_and_brute_force(pair: tuple[np.ndarray, np.ndarray]) -> None:
    a, b = pair
    result = paired_test("A", "B", a, b, resamples=200)
    d = a - b
    assert (result.lower, result.ties, result.higher) == (
        int(np.sum(d < 0)),
        int(np.sum(d == 0)),
        int(np.sum(d > 0)),
    )
    assert result.lower + result.ties + result.higher == result.pairs == a.size
    w_minus, w_plus = _brute_rank_sums(d)
    assert result.rank_sum_lower == pytest.approx(w_minus)
    assert result.rank_sum_higher == pytest.approx(w_plus)
    if np.all(d == 0):
        assert result.p_value == 1.0 and result.favoured is None
    else:
        expected = stats.wilcoxon(a, b, zero_method="wilcox")
        assert result.p_value == pytest.approx(expected.pvalue, rel=1e-9, abs=1e-12)
        # scipy's two-sided statistic is min(W+, W-)
        assert min(w_minus, w_plus) == pytest.approx(expected.statistic)
        one_sided = stats.wilcoxon(a, b, zero_method="wilcox", alternative="less").pvalue
        if result.favoured == "A":  # A lower: the one-sided "A < B" p is the smaller one
            assert one_sided <= 0.5 + 1e-12
    assert result.median_difference.value == pytest.approx(float(np.median(d)))
    low, high = result.median_difference.low, result.median_difference.high
    assert np.min(d) <= low <= high <= np.max(d)
    walsh = [(d[i] + d[j]) / 2.0 for i in range(d.size) for j in range(i, d.size)]
    assert result.hodges_lehmann == pytest.approx(float(np.median(walsh)))


@given(_paired())
def test_paired_test_is_antisymmetric(pair: tuple[np.ndarray, np.ndarray]) -> None:
    a, b = pair
    ab = paired_test("A", "B", a, b, resamples=50)
    ba = paired_test("B", "A", b, a, resamples=50)
    assert (ab.lower, ab.ties, ab.higher) == (ba.higher, ba.ties, ba.lower)
    assert ab.favoured == ba.favoured
    assert ab.p_value == pytest.approx(ba.p_value)
    assert ab.hodges_lehmann == pytest.approx(-ba.hodges_lehmann)


def test_favoured_side_can_disagree_with_strict_counts() -> None:
    """Issue 18's case: A lower on most tasks by a little, higher on few by a lot."""
    b = np.arange(1.0, 21.0)
    a = b.copy()
    a[:12] -= 0.01  # A lower on 12 of 20 tasks, by 0.01
    a[12:] += 5.0  # A higher on 8, by 5
    result = paired_test("A", "B", a, b)
    assert result.lower == 12 and result.higher == 8
    assert result.median_difference.value < 0
    assert result.favoured == "B"  # the signed-rank sums point to B
    assert not result.consistent


@given(
    st.lists(st.tuples(st.booleans(), st.booleans()), min_size=1, max_size=60),
)
def test_mcnemar_exact_against_scipy_binomtest(flags: list[tuple[bool, bool]]) -> None:
    a = np.array([x for x, _ in flags])
    b = np.array([y for _, y in flags])
    result = mcnemar_exact("A", "B", a, b)
    a_only = int(np.sum(a & ~b))
    b_only = int(np.sum(~a & b))
    assert (result.a_only, result.b_only, result.both) == (a_only, b_only, int(np.sum(a & b)))
    if a_only + b_only == 0:
        assert result.p_value == 1.0 and result.favoured is None
    else:
        expected = stats.binomtest(a_only, a_only + b_only, 0.5).pvalue
        assert result.p_value == pytest.approx(expected)
        # brute force: the exact two-sided sign-test p from the binomial pmf
        n = a_only + b_only
        pmf = [math.comb(n, k) / 2**n for k in range(n + 1)]
        brute = sum(p for p in pmf if p <= pmf[a_only] * (1 + 1e-7))
        assert result.p_value == pytest.approx(min(1.0, brute))
    if a_only > b_only:
        assert result.favoured == "A"


@given(st.lists(st.floats(0.0, 1.0, allow_nan=False), min_size=1, max_size=12))
def test_holm_is_monotone_and_bounded(p_values: list[float]) -> None:
    adjusted = holm(p_values)
    m = len(p_values)
    for raw, adj in zip(p_values, adjusted, strict=True):
        assert raw - 1e-15 <= adj <= 1.0
        assert adj <= min(1.0, m * raw) + 1e-15
    order = np.argsort(p_values, kind="stable")
    sorted_adjusted = [adjusted[i] for i in order]
    assert sorted_adjusted == sorted(sorted_adjusted)


def test_paired_ranking_counts_significant_wins_only() -> None:
    rng = np.random.default_rng(3)
    base = rng.lognormal(size=80)
    values = {
        "best": {i: base[i] for i in range(80)},
        "same": {i: base[i] * (1.0 + 0.001 * rng.normal()) for i in range(80)},
        "worse": {i: base[i] + 1.0 for i in range(80)},
    }
    results = paired_comparisons(values, resamples=100)
    points = {name: float(np.median(list(v.values()))) for name, v in values.items()}
    ranking = {r.name: r for r in paired_ranking(points, results)}
    assert ranking["best"].rank == 1 and ranking["same"].rank == 1
    assert ranking["best"].tied and ranking["same"].tied
    assert ranking["worse"].rank == 3 and set(ranking["worse"].beaten_by) == {"best", "same"}


def test_paired_ranking_of_all_equal_data_is_one_tie() -> None:
    values = {name: dict.fromkeys(range(10), 1.0) for name in "abc"}
    results = paired_comparisons(values, resamples=50)
    assert all(r.p_value == 1.0 and r.favoured is None for r in results)
    ranking = paired_ranking(dict.fromkeys("abc", 1.0), results)
    assert [(r.rank, r.tied) for r in ranking] == [(1, True)] * 3


def test_paired_success_and_its_ranking() -> None:
    good = dict.fromkeys(range(40), True)
    bad = {i: i < 10 for i in range(40)}
    results = paired_success({"good": good, "bad": bad})
    assert results[0].a_only + results[0].b_only == 30 and results[0].significant
    ranking = paired_ranking({"good": 1.0, "bad": 0.25}, results, higher_is_better=True)
    assert [(r.name, r.rank) for r in ranking] == [("good", 1), ("bad", 2)]


def test_bootstrap_mc_error_matches_the_seed_to_seed_spread() -> None:
    """The stated Monte-Carlo error is the size of the endpoint change between seeds."""
    data = np.random.default_rng(9).lognormal(size=150)
    lows = [bootstrap_interval(data, seed=s, resamples=400).low for s in range(30)]
    stated = bootstrap_interval(data, seed=0, resamples=400).mc_error
    spread = float(np.std(lows, ddof=1))
    assert 0.4 * spread <= stated <= 2.5 * spread


@given(st.floats(1e-6, 1e6, allow_nan=False), st.floats(1e-9, 1e3, allow_nan=False))
def test_significant_digits_leave_the_error_below_the_last_unit(value: float, error: float) -> None:
    digits = significant_digits(value, error)
    assert 1 <= digits <= 3
    unit = 10.0 ** (math.floor(math.log10(value)) - digits + 1)
    if digits > 1:
        assert unit >= 2.0 * error * 0.999999
    assert significant_digits(value, 0.0) == 3
