r"""Statistics of a study: intervals, paired tests, multiple-testing correction, ranking.

* Wilson score interval of a success rate ``k/n`` at level ``1 − α``:
  :math:`\frac{\hat p + z^2/2n \pm z\sqrt{\hat p(1-\hat p)/n + z^2/4n^2}}{1 + z^2/n}`.
* Percentile bootstrap interval of a median (seeded, ``B`` resamples), with the Monte-Carlo
  standard error of its endpoints (the spread of the endpoints over 10 batches of ``B/10``
  resamples, divided by :math:`\sqrt{10}`), so a report prints only the digits the
  resampling has fixed (:func:`significant_digits`).
* Paired comparison of controllers A and B on the same tasks, :math:`d_i = a_i - b_i`
  (lower wins): the counts strictly lower (:math:`d_i < 0`), tied (:math:`d_i = 0`) and
  higher; the median of :math:`d` with its paired bootstrap interval; the Hodges–Lehmann
  estimate :math:`\operatorname{median}_{i \le j}(d_i + d_j)/2`; the Wilcoxon signed-rank
  test (:func:`scipy.stats.wilcoxon`, zero differences dropped) and *which side it favours*:
  A when the rank sum of the negative differences :math:`W^-` exceeds that of the positive
  ones :math:`W^+`, B when :math:`W^+ > W^-`.
* Paired success rates: the exact McNemar test, i.e. a two-sided binomial (sign) test of
  the discordant tasks (A succeeds and B fails vs the reverse) with :math:`p = 1/2`.
* Holm's step-down correction across the pairs of one family.
* A ranking from those paired tests: the rank of a controller is 1 + the number of
  controllers that beat it in a Holm-significant paired test; controllers with the same
  count share a rank. Nothing else is implied by a shared rank.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, replace
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray
from scipy import stats

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: Batches used to estimate the Monte-Carlo error of bootstrap endpoints.
MC_BATCHES = 10
#: Most significant digits a report prints.
MOST_DIGITS = 3
#: Significance level of the paired tests behind rankings and verdicts (after Holm).
ALPHA = 0.05


def wilson_interval(successes: int, trials: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval ``(low, high)`` of a binomial proportion; ``(0, 1)`` for no trials."""
    if trials <= 0:
        return 0.0, 1.0
    z = float(stats.norm.ppf(0.5 + confidence / 2.0))
    p = successes / trials
    denominator = 1.0 + z * z / trials
    centre = (p + z * z / (2.0 * trials)) / denominator
    half = z * math.sqrt(p * (1.0 - p) / trials + z * z / (4.0 * trials * trials)) / denominator
    return max(0.0, centre - half), min(1.0, centre + half)


@dataclass(frozen=True)
class Interval:
    """A point value and its bootstrap interval.

    Attributes:
        value: The statistic of the data (exact, no resampling in it).
        low: Lower endpoint.
        high: Upper endpoint.
        mc_error: Monte-Carlo standard error of the endpoints (the larger of the two); 0 when
            every batch gave the same endpoints.
    """

    value: float
    low: float
    high: float
    mc_error: float = 0.0

    def as_tuple(self) -> tuple[float, float, float]:
        """``(value, low, high)``."""
        return self.value, self.low, self.high


NO_INTERVAL = Interval(math.nan, math.nan, math.nan, math.nan)


def significant_digits(value: float, error: float, most: int = MOST_DIGITS) -> int:
    r"""Significant digits of ``value`` whose last unit is at least twice ``error``.

    :math:`s = \lfloor\log_{10}|v|\rfloor - \lceil\log_{10} 2e\rceil + 1`, clipped to
    ``[1, most]``; ``most`` when the error is 0 (or the value is 0 / not finite).
    """
    if not (math.isfinite(value) and math.isfinite(error)) or value == 0.0 or error <= 0.0:
        return most
    digits = math.floor(math.log10(abs(value))) - math.ceil(math.log10(2.0 * error)) + 1
    return max(1, min(most, digits))


def _resample_indices(seed: int, size: int, resamples: int) -> Iterator[IntArray]:
    """Index blocks ``(count, size)`` of ``default_rng(seed).choice(size, replace=True)``.

    The draws ``rng.choice(data, ...)`` makes for any ``data`` of this size (blocks of ≤ 2·10⁶
    values), each row sorted. Cached (:func:`_sorted_indices`) up to :data:`CACHED_DRAWS`
    values: a report bootstraps thousands of samples of the same size with the same seed.
    """
    if size * resamples <= CACHED_DRAWS:
        yield from _sorted_indices(seed, size, resamples)
        return
    yield from _draw_sorted(seed, size, resamples)


#: Most index values kept per cached (seed, size, resamples) draw (8 bytes each).
CACHED_DRAWS = 4_000_000


def _draw_sorted(seed: int, size: int, resamples: int) -> Iterator[IntArray]:
    rng = np.random.default_rng(seed)
    block = max(1, 2_000_000 // max(1, size))
    for start in range(0, resamples, block):
        count = min(block, resamples - start)
        yield np.sort(rng.choice(size, size=(count, size), replace=True), axis=1)


@functools.lru_cache(maxsize=16)
def _sorted_indices(seed: int, size: int, resamples: int) -> tuple[IntArray, ...]:
    blocks = tuple(_draw_sorted(seed, size, resamples))
    for block in blocks:
        block.setflags(write=False)
    return blocks


def _resampled_medians(data: FloatArray, seed: int, resamples: int) -> FloatArray:
    r"""Medians of ``resamples`` resamples of the sorted ``data`` with replacement.

    The resamples are ``default_rng(seed).choice(data, (resamples, n), replace=True)``; as
    ``data`` is sorted, a resample's median is that of its middle sorted indices:
    :math:`x_{(i_{m})}` for odd n, :math:`(x_{(i_{m-1})} + x_{(i_m)})/2` for even n — the
    values :func:`numpy.median` returns, bit for bit, without sorting each resample's values.
    """
    n = data.size
    half = n // 2
    medians = np.empty(resamples)
    start = 0
    for block in _resample_indices(seed, n, resamples):
        out = medians[start : start + block.shape[0]]
        if n % 2:
            np.take(data, block[:, half], out=out)
        else:
            np.add(data[block[:, half - 1]], data[block[:, half]], out=out)
            out /= 2.0
        start += block.shape[0]
    return medians


def bootstrap_interval(
    values: FloatArray, seed: int = 0, resamples: int = 2000, confidence: float = 0.95
) -> Interval:
    """Median and its percentile-bootstrap interval with the endpoints' Monte-Carlo error.

    Resamples with replacement (``numpy.random.default_rng(seed)``), takes the medians and
    their ``(1 ± confidence)/2`` quantiles. The values are sorted first, so the interval does
    not depend on their order (a Dask study stores episodes in completion order). NaN/inf
    values are dropped; no finite value gives :data:`NO_INTERVAL`.
    """
    data = np.asarray(values, dtype=float)
    data = np.sort(data[np.isfinite(data)])
    if data.size == 0:
        return NO_INTERVAL
    medians = _resampled_medians(data, seed, resamples)
    alpha = (1.0 - confidence) / 2.0
    low, high = np.quantile(medians, [alpha, 1.0 - alpha])
    error = 0.0
    if resamples >= 2 * MC_BATCHES:
        batches = medians[: resamples - resamples % MC_BATCHES].reshape(MC_BATCHES, -1)
        ends = np.quantile(batches, [alpha, 1.0 - alpha], axis=1)  # (2, batches)
        error = float(np.max(np.std(ends, axis=1, ddof=1)) / math.sqrt(MC_BATCHES))
    return Interval(float(np.median(data)), float(low), float(high), error)


def bootstrap_median(
    values: FloatArray, seed: int = 0, resamples: int = 2000, confidence: float = 0.95
) -> tuple[float, float, float]:
    """``(median, low, high)`` of :func:`bootstrap_interval`; NaNs for no data."""
    return bootstrap_interval(values, seed, resamples, confidence).as_tuple()


def holm(p_values: list[float]) -> list[float]:
    r"""Holm step-down adjusted p-values (same order as given), capped at 1.

    :math:`\tilde p_{(i)} = \max_{j \le i} \min(1, (m - j + 1)\,p_{(j)})` for sorted p.
    """
    m = len(p_values)
    order = sorted(range(m), key=lambda i: p_values[i])
    adjusted = [0.0] * m
    running = 0.0
    for rank, index in enumerate(order):
        running = max(running, min(1.0, (m - rank) * p_values[index]))
        adjusted[index] = running
    return adjusted


@dataclass(frozen=True)
class PairedResult:
    r"""A vs B on one lower-is-better metric over the tasks both ran, :math:`d = a - b`.

    Attributes:
        a: Controller A.
        b: Controller B.
        pairs: Number of paired tasks.
        lower: Tasks where A is strictly lower (:math:`d < 0`).
        ties: Tasks where A and B are equal.
        higher: Tasks where A is strictly higher.
        median_difference: Median of ``a − b`` and its paired bootstrap interval.
        hodges_lehmann: Median of the Walsh averages :math:`(d_i + d_j)/2, i \le j`.
        rank_sum_lower: :math:`W^-`, the signed-rank sum of the tasks where A is lower.
        rank_sum_higher: :math:`W^+`, the signed-rank sum of the tasks where A is higher.
        p_value: Wilcoxon signed-rank p-value (1 when every difference is zero).
        p_holm: Holm-adjusted p-value (set by :func:`paired_comparisons`).
    """

    a: str
    b: str
    pairs: int
    lower: int
    ties: int
    higher: int
    median_difference: Interval
    hodges_lehmann: float
    rank_sum_lower: float
    rank_sum_higher: float
    p_value: float
    p_holm: float = math.nan

    @property
    def favoured(self) -> str | None:
        """The side the signed-rank test favours (the lower one), or None when W⁻ = W⁺."""
        if self.rank_sum_lower > self.rank_sum_higher:
            return self.a
        if self.rank_sum_higher > self.rank_sum_lower:
            return self.b
        return None

    @property
    def consistent(self) -> bool:
        """Whether the strict counts and the median difference point to the favoured side too."""
        side = self.favoured
        if side is None:
            return True
        towards_a = side == self.a
        counts = self.lower > self.higher if towards_a else self.higher > self.lower
        median = self.median_difference.value
        return counts and (median < 0 if towards_a else median > 0)

    @property
    def significant(self) -> bool:
        """Holm-adjusted p below :data:`ALPHA`."""
        return self.p_holm < ALPHA


def average_ranks(values: FloatArray) -> FloatArray:
    """Ranks 1..n of ``values`` (n,), ties sharing their average rank.

    :func:`scipy.stats.rankdata` with ``method="average"``, its algorithm and values bit for
    bit, without its per-call dispatch (the report ranks hundreds of thousands of samples).
    """
    x = np.asarray(values, dtype=float).ravel()
    order = np.argsort(x, kind="mergesort")
    ordered = x[order]
    first = np.empty(x.size, dtype=bool)
    first[:1] = True
    np.not_equal(ordered[1:], ordered[:-1], out=first[1:])
    dense = np.cumsum(first)[np.argsort(order, kind="mergesort")]
    count = np.r_[np.nonzero(first)[0], x.size]
    return 0.5 * (count[dense] + count[dense - 1] + 1)


def signed_rank_sums(differences: FloatArray) -> tuple[float, float]:
    """``(W⁻, W⁺)``: sums of the average ranks of ``|d|`` over the negative / positive ``d``.

    Zero differences are dropped first (Wilcoxon's convention, ``zero_method="wilcox"``).
    """
    d = np.asarray(differences, dtype=float)
    d = d[d != 0.0]
    if d.size == 0:
        return 0.0, 0.0
    ranks = average_ranks(np.abs(d))
    return float(ranks[d < 0].sum()), float(ranks[d > 0].sum())


def hodges_lehmann(differences: FloatArray) -> float:
    r"""One-sample Hodges–Lehmann estimate: :math:`\operatorname{median}_{i \le j}(d_i + d_j)/2`."""
    d = np.asarray(differences, dtype=float)
    if d.size == 0:
        return math.nan
    upper = np.triu_indices(d.size)
    return float(np.median((d[upper[0]] + d[upper[1]]) / 2.0))


def _finite_pairs(a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    keep = np.isfinite(a) & np.isfinite(b)
    return a[keep], b[keep]


def wilcoxon_p(a: FloatArray, b: FloatArray) -> float:
    """Two-sided Wilcoxon signed-rank p of ``a − b`` over the finite pairs, shape ``(n,)`` each.

    1 when every difference is zero, NaN without a finite pair (the p of :func:`paired_test`).
    """
    a, b = _finite_pairs(a, b)
    if a.size == 0:
        return math.nan
    difference = a - b
    if not np.any(difference != 0.0):
        return 1.0
    if difference.size <= EXACT_PAIRS:
        return exact_signed_rank_p(difference)
    return float(stats.wilcoxon(difference, zero_method="wilcox").pvalue)


#: Up to this many pairs (zeros included) the signed-rank p is the exact enumeration of
#: every sign pattern — what :func:`scipy.stats.wilcoxon` does there too (its exact
#: distribution without ties, a deterministic permutation test with ties or zeros), without
#: its per-pattern Python loop.
EXACT_PAIRS = 13


def exact_signed_rank_p(differences: FloatArray) -> float:
    r"""Two-sided exact p of the signed-rank statistic over all :math:`2^m` sign patterns.

    :math:`W^+ = \sum_{d_i > 0} r_i` with :math:`r` the average ranks of the *m* non-zero
    :math:`|d_i|`; :math:`p = \min(1, 2\min(P(T \le W^+), P(T \ge W^+)))` for
    :math:`T = \sum_i s_i r_i`, :math:`s \in \{0, 1\}^m` uniform, with scipy's relative
    tolerance :math:`100\,\varepsilon\,W^+` on the comparisons. Shape ``(n,)``, ``m ≤ 20``.
    """
    d = np.asarray(differences, dtype=float)
    d = d[d != 0.0]
    if d.size == 0:
        return 1.0
    ranks = average_ranks(np.abs(d))
    observed = float(ranks[d > 0].sum())
    null = _sign_patterns(d.size) @ ranks
    gamma = abs(np.finfo(float).eps * 100 * observed)
    less = np.count_nonzero(null <= observed + gamma) / null.size
    greater = np.count_nonzero(null >= observed - gamma) / null.size
    return float(min(1.0, 2.0 * min(less, greater)))


@functools.lru_cache(maxsize=EXACT_PAIRS + 1)
def _sign_patterns(m: int) -> IntArray:
    """Every 0/1 sign pattern of ``m`` ranks, shape ``(2**m, m)`` (read-only, cached)."""
    patterns = (np.arange(2**m)[:, None] >> np.arange(m)) & 1
    patterns.setflags(write=False)
    return patterns


def paired_test(
    a_name: str, b_name: str, a: FloatArray, b: FloatArray, seed: int = 0, resamples: int = 2000
) -> PairedResult:
    """Counts, effect with its interval and Wilcoxon test of paired samples (finite pairs only)."""
    a, b = _finite_pairs(a, b)
    n = int(a.size)
    if n == 0:
        return PairedResult(a_name, b_name, 0, 0, 0, 0, NO_INTERVAL, math.nan, 0.0, 0.0, math.nan)
    difference = a - b
    lower = int(np.count_nonzero(difference < 0))
    higher = int(np.count_nonzero(difference > 0))
    p = wilcoxon_p(a, b)
    w_minus, w_plus = signed_rank_sums(difference)
    return PairedResult(
        a_name,
        b_name,
        n,
        lower,
        n - lower - higher,
        higher,
        bootstrap_interval(difference, seed, resamples),
        hodges_lehmann(difference),
        w_minus,
        w_plus,
        p,
    )


@dataclass(frozen=True)
class PairedRates:
    """Success of A vs B on the same tasks: the exact McNemar (sign) test.

    Attributes:
        a: Controller A.
        b: Controller B.
        pairs: Paired tasks.
        a_only: Tasks where A succeeds and B fails.
        b_only: Tasks where B succeeds and A fails.
        both: Tasks where both succeed.
        p_value: Two-sided exact binomial p of ``a_only`` in ``a_only + b_only`` at 1/2
            (1 with no discordant task).
        p_holm: Holm-adjusted p-value (set by :func:`paired_success`).
    """

    a: str
    b: str
    pairs: int
    a_only: int
    b_only: int
    both: int
    p_value: float
    p_holm: float = math.nan

    @property
    def favoured(self) -> str | None:
        """The controller with more discordant successes, or None on a tie."""
        if self.a_only > self.b_only:
            return self.a
        if self.b_only > self.a_only:
            return self.b
        return None

    @property
    def significant(self) -> bool:
        """Holm-adjusted p below :data:`ALPHA`."""
        return self.p_holm < ALPHA


def mcnemar_exact(
    a_name: str, b_name: str, a: NDArray[np.bool_], b: NDArray[np.bool_]
) -> PairedRates:
    """Exact McNemar test of paired success flags (same tasks, same order)."""
    a = np.asarray(a, dtype=bool)
    b = np.asarray(b, dtype=bool)
    a_only = int(np.count_nonzero(a & ~b))
    b_only = int(np.count_nonzero(~a & b))
    both = int(np.count_nonzero(a & b))
    discordant = a_only + b_only
    p = 1.0 if discordant == 0 else float(stats.binomtest(a_only, discordant, 0.5).pvalue)
    return PairedRates(a_name, b_name, int(a.size), a_only, b_only, both, p)


Result = TypeVar("Result", PairedResult, PairedRates)


def with_holm(results: list[Result]) -> list[Result]:
    """The results with ``p_holm`` set across those with a finite p (others keep NaN)."""
    tested = [i for i, r in enumerate(results) if math.isfinite(r.p_value)]
    adjusted = holm([results[i].p_value for i in tested])
    out = list(results)
    for i, p in zip(tested, adjusted, strict=True):
        out[i] = replace(results[i], p_holm=p)
    return out


def _pairs(names: list[str]) -> list[tuple[str, str]]:
    return [(a, b) for i, a in enumerate(names) for b in names[i + 1 :]]


def paired_comparisons(
    values: Mapping[str, Mapping[Any, float]], seed: int = 0, resamples: int = 2000
) -> list[PairedResult]:
    """Every pair of controllers on their common tasks, Holm-corrected across the pairs.

    Args:
        values: ``controller → {task key → metric value}``.
        seed: Bootstrap seed of the median differences.
        resamples: Bootstrap resamples.
    """
    results = []
    for a, b in _pairs(sorted(values)):
        common = sorted(set(values[a]) & set(values[b]), key=str)
        results.append(
            paired_test(
                a,
                b,
                np.array([values[a][k] for k in common], dtype=float),
                np.array([values[b][k] for k in common], dtype=float),
                seed,
                resamples,
            )
        )
    return with_holm(results)


def paired_success(values: Mapping[str, Mapping[Any, bool]]) -> list[PairedRates]:
    """Exact McNemar test of every pair on their common tasks, Holm-corrected across pairs.

    Args:
        values: ``controller → {task key → success}``.
    """
    results = []
    for a, b in _pairs(sorted(values)):
        common = sorted(set(values[a]) & set(values[b]), key=str)
        results.append(
            mcnemar_exact(
                a,
                b,
                np.array([values[a][k] for k in common], dtype=bool),
                np.array([values[b][k] for k in common], dtype=bool),
            )
        )
    return with_holm(results)


@dataclass(frozen=True)
class Ranked:
    """One controller's place in a paired-test ranking.

    Attributes:
        name: Controller.
        rank: 1 + the number of controllers that beat it in a Holm-significant paired test.
        tied: Another controller has the same rank.
        beaten_by: The controllers that beat it.
    """

    name: str
    rank: int
    tied: bool
    beaten_by: tuple[str, ...]


def paired_ranking(
    points: Mapping[str, float],
    results: list[PairedResult] | list[PairedRates],
    higher_is_better: bool = False,
) -> list[Ranked]:
    """Rank controllers by the Holm-significant paired tests among them.

    Args:
        points: ``name → point value`` (median or rate), used only to order equal ranks.
        results: Paired results between those names (see :func:`paired_comparisons`,
            :func:`paired_success`); a pair counts when ``significant`` and ``favoured`` is set.
        higher_is_better: Order equal ranks by descending point value.

    Returns:
        Sorted by rank, then by point value (better first), then name.
    """
    beaten: dict[str, list[str]] = {name: [] for name in points}
    for result in results:
        winner = result.favoured
        if not result.significant or winner is None:
            continue
        loser = result.b if winner == result.a else result.a
        if loser in beaten and winner in points:
            beaten[loser].append(winner)
    ranks = {name: 1 + len(set(by)) for name, by in beaten.items()}
    counts: dict[int, int] = {}
    for rank in ranks.values():
        counts[rank] = counts.get(rank, 0) + 1
    sign = -1.0 if higher_is_better else 1.0

    def order(name: str) -> tuple[int, float, str]:
        value = points[name]
        return ranks[name], sign * value if math.isfinite(value) else math.inf, name

    return [
        Ranked(n, ranks[n], counts[ranks[n]] > 1, tuple(sorted(set(beaten[n]))))
        for n in sorted(points, key=order)
    ]


def rank_with_ties(
    intervals: dict[str, tuple[float, float, float]], higher_is_better: bool = False
) -> list[tuple[str, int, bool]]:
    """Rank by point value; a controller's rank is 1 + the number clearly better than it.

    "Clearly better" means its interval lies entirely on the better side of this one's
    interval (an unpaired comparison: the study report ranks by :func:`paired_ranking`).

    Args:
        intervals: ``name → (value, low, high)``.
        higher_is_better: Success rates: True; errors and speeds: False.

    Returns:
        ``(name, rank, tied)`` sorted by rank then value.
    """
    ranks = {}
    for name, (_, low, high) in intervals.items():
        better = 0
        for other, (_, o_low, o_high) in intervals.items():
            if other == name:
                continue
            if higher_is_better and o_low > high:
                better += 1
            if not higher_is_better and o_high < low:
                better += 1
        ranks[name] = 1 + better
    counts: dict[int, int] = {}
    for rank in ranks.values():
        counts[rank] = counts.get(rank, 0) + 1
    sign = -1.0 if higher_is_better else 1.0

    def order(name: str) -> tuple[int, float]:
        value = intervals[name][0]
        return ranks[name], sign * (value if math.isfinite(value) else math.inf)

    return [(n, ranks[n], counts[ranks[n]] > 1) for n in sorted(intervals, key=order)]


def binned_medians(
    x: FloatArray, y: FloatArray, edges: FloatArray
) -> tuple[FloatArray, FloatArray, NDArray[np.int64]]:
    """Median of ``y`` in each bin ``[edges[i], edges[i+1])`` of ``x``: centres, medians, counts."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    keep = np.isfinite(x) & np.isfinite(y)
    x, y = x[keep], y[keep]
    centres = (
        np.sqrt(edges[:-1] * edges[1:]) if np.all(edges > 0) else 0.5 * (edges[:-1] + edges[1:])
    )
    medians = np.full(centres.size, np.nan)
    counts = np.zeros(centres.size, dtype=np.int64)
    for i in range(centres.size):
        last = i == centres.size - 1
        inside = (x >= edges[i]) & ((x <= edges[i + 1]) if last else (x < edges[i + 1]))
        counts[i] = int(np.count_nonzero(inside))
        if counts[i]:
            medians[i] = float(np.median(y[inside]))
    return centres, medians, counts
