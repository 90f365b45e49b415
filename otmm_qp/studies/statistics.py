r"""Statistics of a study: intervals, paired tests, multiple-testing correction, ranking.

* Wilson score interval of a success rate ``k/n`` at level ``1 − α``:
  :math:`\frac{\hat p + z^2/2n \pm z\sqrt{\hat p(1-\hat p)/n + z^2/4n^2}}{1 + z^2/n}`.
* Percentile bootstrap interval of a median (seeded, ``B`` resamples).
* Paired comparison of controllers A and B on the same tasks: win rate
  :math:`\frac{\#\{a_i < b_i\} + \frac12\#\{a_i = b_i\}}{n}` (lower metric wins) and the
  Wilcoxon signed-rank test (:func:`scipy.stats.wilcoxon`), Holm-corrected across pairs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import stats

FloatArray = NDArray[np.float64]


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


def bootstrap_median(
    values: FloatArray, seed: int = 0, resamples: int = 2000, confidence: float = 0.95
) -> tuple[float, float, float]:
    """Median and its percentile-bootstrap interval ``(median, low, high)``; NaNs for no data.

    Resamples with replacement (``numpy.random.default_rng(seed)``), takes the medians and
    their ``(1 ± confidence)/2`` quantiles. The values are sorted first, so the interval does
    not depend on their order (a Dask study stores episodes in completion order).
    """
    data = np.asarray(values, dtype=float)
    data = np.sort(data[np.isfinite(data)])
    if data.size == 0:
        return math.nan, math.nan, math.nan
    rng = np.random.default_rng(seed)
    samples = rng.choice(data, size=(resamples, data.size), replace=True)
    medians = np.median(samples, axis=1)
    alpha = (1.0 - confidence) / 2.0
    low, high = np.quantile(medians, [alpha, 1.0 - alpha])
    return float(np.median(data)), float(low), float(high)


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
    """A vs B on one metric over the tasks both ran.

    Attributes:
        a: Controller A.
        b: Controller B.
        pairs: Number of paired tasks.
        win_rate: Fraction of tasks where A is lower (ties count half).
        median_difference: Median of ``a − b``.
        p_value: Wilcoxon signed-rank p-value (1 when every difference is zero).
        p_holm: Holm-adjusted p-value (set by :func:`paired_comparisons`).
    """

    a: str
    b: str
    pairs: int
    win_rate: float
    median_difference: float
    p_value: float
    p_holm: float = math.nan


def paired_test(a_name: str, b_name: str, a: FloatArray, b: FloatArray) -> PairedResult:
    """Win rate and Wilcoxon signed-rank test of paired samples (finite pairs only)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    keep = np.isfinite(a) & np.isfinite(b)
    a, b = a[keep], b[keep]
    n = int(a.size)
    if n == 0:
        return PairedResult(a_name, b_name, 0, math.nan, math.nan, math.nan)
    difference = a - b
    wins = float(np.count_nonzero(difference < 0) + 0.5 * np.count_nonzero(difference == 0))
    if np.all(difference == 0):
        p = 1.0
    else:
        p = float(stats.wilcoxon(a, b, zero_method="wilcox").pvalue)
    return PairedResult(a_name, b_name, n, wins / n, float(np.median(difference)), p)


def paired_comparisons(
    values: dict[str, dict[tuple[object, ...], float]],
) -> list[PairedResult]:
    """Every pair of controllers on their common tasks, Holm-corrected across the pairs.

    Args:
        values: ``controller → {task key → metric value}``.
    """
    names = sorted(values)
    results = []
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            common = sorted(set(values[a]) & set(values[b]), key=str)
            results.append(
                paired_test(
                    a,
                    b,
                    np.array([values[a][k] for k in common], dtype=float),
                    np.array([values[b][k] for k in common], dtype=float),
                )
            )
    tested = [r for r in results if not math.isnan(r.p_value)]
    adjusted = holm([r.p_value for r in tested])
    out = []
    for result in results:
        if math.isnan(result.p_value):
            out.append(result)
        else:
            out.append(
                PairedResult(
                    result.a,
                    result.b,
                    result.pairs,
                    result.win_rate,
                    result.median_difference,
                    result.p_value,
                    adjusted[tested.index(result)],
                )
            )
    return out


def rank_with_ties(
    intervals: dict[str, tuple[float, float, float]], higher_is_better: bool = False
) -> list[tuple[str, int, bool]]:
    """Rank by point value; a controller's rank is 1 + the number clearly better than it.

    "Clearly better" means its interval lies entirely on the better side of this one's
    interval. Controllers whose intervals overlap thus share a rank (``tied`` = True when
    another controller has the same rank).

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
