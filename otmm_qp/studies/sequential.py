r"""Anytime-valid success decisions: a mixture sequential test on the discordant tasks.

A study with ``decide:`` looks at its rows after every batch and stops as soon as one row is
better than every other on success. A fixed-sample test (exact McNemar) applied at each look
declares a winner between rows of *equal* success rates far more often than its α (see
``benchmarks/bench_decide.py``). This module's rule holds its error rate **whatever the
number of looks and whenever the study stops**.

**The test of one pair.** Rows A and B on the same tasks: a task is *discordant* when exactly
one of them succeeds. Among the ``n`` discordant tasks so far A alone succeeds on ``k``; if
A and B succeed equally often (``P(A only) = P(B only)``), each discordant task is A's with
probability 1/2, whatever the tasks are and however they were drawn. With a Beta(a, a) prior
on A's share θ restricted to θ > 1/2 (density doubled), the mixture likelihood ratio

.. math:: E_{A>B} = 2\int_{1/2}^{1} \frac{θ^k (1-θ)^{n-k}}{(1/2)^n}\,
          \frac{θ^{a-1}(1-θ)^{a-1}}{B(a, a)}\,dθ
          = 2^{n+1}\,\frac{B(k+a, n-k+a)}{B(a, a)}\,I_{1/2}(n-k+a,\,k+a)

(:math:`I` the regularized incomplete beta function) is a non-negative supermartingale in the
tasks for every θ ≤ 1/2 (each factor ``2(θθ₀ + (1-θ)(1-θ₀)) ≤ 1`` for θ > 1/2 ≥ θ₀, and a
concordant task leaves it unchanged), starting at 1: an *e-process* for "A is not better than
B". Ville's inequality gives ``P(sup_t E ≥ 1/α) ≤ α`` — a claim "A beats B" made when
``E_{A>B} ≥ 1/α`` at *any* look, however the looks are chosen, is wrong with probability at
most α.

**Many rows (Bonferroni on e-values).** With ``r`` rows there are ``r(r-1)`` directional
claims; each is made at ``E ≥ r(r-1)/α`` (:func:`threshold`), so the chance that *any* false
claim is ever made is ≤ α (union bound, anytime). A row is *decided* (:func:`pick`) when it
beats every other row so: the probability that a study ever names a row that is not truly
better than every other is ≤ α, for any stopping rule — after every batch, after every task,
or when the budget is spent.

**Final numbers valid under the stopping rule.** The anytime-valid p-value of a claim is
``min(1, r(r-1)/E)`` (:attr:`PairEvidence.p_anytime`: ``P(p ≤ α) ≤ α`` at any stopping time),
and A's share θ of the discordant tasks has the confidence sequence

.. math:: \{θ : B(k+a, n-k+a)/B(a, a) < θ^k (1-θ)^{n-k} / α'\}

at ``α' = α / (r(r-1)/2)`` (the two-sided Beta(a, a) mixture inverted, Robbins 1970): it covers
the true share at every look simultaneously with probability ≥ 1 − α'. The
:data:`PRIOR` ``a = 8`` puts most of the prior's mass at shares 0.55–0.8 (the range where rows
of a study differ); the test stays valid for any ``a``, only its power changes.

The rule is a pure function of the paired counts (:func:`pick_from_counts`), so the
simulation drives exactly what a study runs. :func:`fixed_sample_pick` is the rule studies
used before (exact McNemar, Holm, at every look), kept as the simulation's baseline.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.special import betainc, betaln
from scipy.stats import binom

from otmm_qp.studies.sizing import smallest_enough
from otmm_qp.studies.statistics import ALPHA, holm

__all__ = [
    "PRIOR",
    "PairEvidence",
    "SequentialVerdict",
    "confidence_sequence",
    "discordant_counts",
    "fixed_sample_pick",
    "log_e_value",
    "pick",
    "pick_from_counts",
    "tasks_to_decide",
    "threshold",
]

#: Beta(a, a) prior parameter of the mixture (see the module docstring).
PRIOR = 8.0


def threshold(rows: int, alpha: float = ALPHA) -> float:
    """The e-value a directional claim needs among ``rows`` rows: ``r(r-1)/α`` (Bonferroni)."""
    return max(rows * (rows - 1), 1) / alpha


def log_e_value(
    wins: NDArray[np.int64] | int, discordant: NDArray[np.int64] | int, prior: float = PRIOR
) -> NDArray[np.float64]:
    """``log E_{A>B}`` for ``wins`` of ``discordant`` tasks (see the module; elementwise).

    Args:
        wins: Discordant tasks the first row alone succeeds on (``k``).
        discordant: Discordant tasks (``n ≥ k``).
        prior: The Beta(a, a) parameter ``a > 0``.

    Returns:
        ``log E`` (0 with no discordant task), an array of the broadcast shape.
    """
    k = np.asarray(wins, dtype=float)
    n = np.asarray(discordant, dtype=float)
    upper = betainc(n - k + prior, k + prior, 0.5)  # I_{1/2}(n-k+a, k+a) = P(θ > 1/2 | data)
    with np.errstate(divide="ignore"):
        log_upper = np.log(upper)
    out = (n + 1.0) * math.log(2.0) + betaln(k + prior, n - k + prior) - betaln(prior, prior)
    return np.asarray(out + log_upper, dtype=float)


def discordant_counts(success: NDArray[np.bool_]) -> NDArray[np.int64]:
    """``only[i, j]``: tasks where row ``i`` succeeds and row ``j`` fails.

    Args:
        success: Success flags, shape ``(tasks, rows)`` (the same tasks for every row).
    """
    flags = np.asarray(success, dtype=np.int64)
    return np.asarray(flags.T @ (1 - flags), dtype=np.int64)


def pick_from_counts(
    only: NDArray[np.int64], alpha: float = ALPHA, prior: float = PRIOR
) -> int | None:
    """The row that beats every other by the anytime test, or None (the study's rule).

    Args:
        only: ``only[i, j]`` of :func:`discordant_counts` (square, ``rows × rows``).
        alpha: Family-wise error rate over every directional claim, at any stopping time.
        prior: The mixture's Beta(a, a) parameter.
    """
    only = np.asarray(only, dtype=np.int64)
    rows = only.shape[0]
    if rows < 2:
        return None
    log_e = log_e_value(only, only + only.T, prior)
    beats = log_e >= math.log(threshold(rows, alpha))
    np.fill_diagonal(beats, True)
    winners = np.flatnonzero(beats.all(axis=1))
    return int(winners[0]) if winners.size else None


@lru_cache(maxsize=4096)
def _mcnemar_p(discordant: int) -> NDArray[np.float64]:
    """Two-sided exact binomial p of every ``k`` in ``0..discordant`` at 1/2."""
    k = np.arange(discordant + 1)
    tails = np.minimum(binom.cdf(k, discordant, 0.5), binom.sf(k - 1, discordant, 0.5))
    return np.asarray(np.minimum(1.0, 2.0 * tails), dtype=float)


def fixed_sample_pick(only: NDArray[np.int64], alpha: float = ALPHA) -> int | None:
    """The rule before issue 36: exact McNemar per pair, Holm, a row beating every other.

    Valid for one look only; at a look after every batch its false-decision rate exceeds
    ``alpha`` (the simulation's baseline). Equal to the former ``decide.decided`` on the
    same rows (``tests/studies/test_sequential.py``).
    """
    only = np.asarray(only, dtype=np.int64)
    rows = only.shape[0]
    if rows < 2:
        return None
    pairs = [(i, j) for i in range(rows) for j in range(i + 1, rows)]
    p = [
        float(_mcnemar_p(int(only[i, j] + only[j, i]))[only[i, j]])
        if only[i, j] + only[j, i]
        else 1.0
        for i, j in pairs
    ]
    adjusted = holm(p)
    beats = np.eye(rows, dtype=bool)
    for (i, j), q in zip(pairs, adjusted, strict=True):
        if q < alpha and only[i, j] != only[j, i]:
            winner, loser = (i, j) if only[i, j] > only[j, i] else (j, i)
            beats[winner, loser] = True
    winners = np.flatnonzero(beats.all(axis=1))
    return int(winners[0]) if winners.size else None


def confidence_sequence(
    wins: int, discordant: int, alpha: float, prior: float = PRIOR
) -> tuple[float, float]:
    """Anytime-valid interval of the first row's share θ of the discordant tasks.

    ``{θ : log B(k+a, n-k+a) − log B(a, a) − k log θ − (n-k) log(1-θ) < log(1/α)}``, an
    interval (the left side is convex in θ); ``(0, 1)`` with no discordant task.
    """
    k, n = wins, discordant
    if n == 0:
        return 0.0, 1.0
    mixture = float(betaln(k + prior, n - k + prior) - betaln(prior, prior))
    bound = math.log(1.0 / alpha)

    def excess(theta: float) -> float:  # > 0 outside the sequence
        log_lik = (k * math.log(theta) if k else 0.0) + (
            (n - k) * math.log1p(-theta) if n - k else 0.0
        )
        return mixture - log_lik - bound

    centre = min(max(k / n, 1e-12), 1 - 1e-12)

    def edge(outside: float) -> float:
        inside = centre
        if excess(outside) <= 0.0:  # the sequence reaches the end of the unit interval
            return 0.0 if outside < 0.5 else 1.0
        for _ in range(60):  # bisection to ~1e-18 of the unit interval
            middle = 0.5 * (inside + outside)
            if excess(middle) > 0.0:
                outside = middle
            else:
                inside = middle
        return inside

    return edge(1e-12), edge(1 - 1e-12)


@dataclass(frozen=True)
class PairEvidence:
    """The anytime evidence that ``leader`` beats ``other`` on success.

    Attributes:
        leader: The row the claim favours.
        other: The other row.
        tasks: Tasks both ran.
        leader_only: Tasks the leader alone succeeds on.
        other_only: Tasks the other alone succeeds on.
        e_value: ``E_{leader>other}`` (:func:`log_e_value`, exponentiated; may be inf).
        needed: The e-value a claim needs (:func:`threshold`).
        share: Leader's share of the discordant tasks, ``(low, high)`` (confidence sequence
            at α / pairs; valid whenever the study stopped).
    """

    leader: str
    other: str
    tasks: int
    leader_only: int
    other_only: int
    e_value: float
    needed: float
    share: tuple[float, float]

    @property
    def beaten(self) -> bool:
        """The claim is made: ``E ≥`` the threshold."""
        return self.e_value >= self.needed

    @property
    def p_anytime(self) -> float:
        """Anytime-valid p of the claim, Bonferroni-adjusted: ``min(1, needed·α / E)``."""
        return min(1.0, self.needed * ALPHA / self.e_value) if self.e_value > 0 else 1.0


@dataclass(frozen=True)
class SequentialVerdict:
    """The anytime decision over some tasks: the pick, or the leader and what it lacks.

    Attributes:
        rates: ``row → success rate`` [0, 1] on its tasks.
        tasks: Distinct tasks.
        pick: The row that beats every other (:func:`pick_from_counts`), or None.
        leader: The pick, else the best rate (ties by name); None without rows.
        evidence: The leader against each other row (closest first: smallest e-value).
        group: The rows no row beats, when each of them beats every row outside it (and some
            row is outside): the same family of claims as the pick (a row of the group is
            the pick when it is alone); empty otherwise.
    """

    rates: dict[str, float]
    tasks: int
    pick: str | None
    leader: str | None
    evidence: tuple[PairEvidence, ...] = ()
    group: tuple[str, ...] = ()

    @property
    def decided(self) -> bool:
        """A row beats every other."""
        return self.pick is not None


def pick(
    flags: Mapping[str, Mapping[Any, bool]], alpha: float = ALPHA, prior: float = PRIOR
) -> SequentialVerdict:
    """The anytime decision of rows ``name → {task key → success}`` (their common tasks).

    Tasks not run by every row are left out of the paired counts (a generation failure is
    an error row for every row, concordant: it moves no count).
    """
    names = sorted(flags)
    rates = {n: sum(flags[n].values()) / len(flags[n]) if flags[n] else 0.0 for n in names}
    tasks = len(set().union(*(set(f) for f in flags.values()))) if flags else 0
    if len(names) < 2:
        lone = names[0] if names else None
        return SequentialVerdict(rates, tasks, None, lone)
    common: Sequence[Any] = sorted(set.intersection(*(set(flags[n]) for n in names)), key=str)
    success = np.array([[flags[n][key] for n in names] for key in common], dtype=bool)
    only = discordant_counts(success.reshape(len(common), len(names)))
    winner = pick_from_counts(only, alpha, prior)
    chosen = names[winner] if winner is not None else None
    beats = log_e_value(only, only + only.T, prior) >= math.log(threshold(len(names), alpha))
    free = np.asarray(~beats.any(axis=0), dtype=bool)  # rows no row beats
    separated = free.any() and not free.all() and beats[np.ix_(free, ~free)].all()
    group = tuple(names[i] for i in np.flatnonzero(free)) if separated else ()
    leader = chosen or max(names, key=lambda n: (rates[n], n))
    i = names.index(leader)
    need = threshold(len(names), alpha)
    level = alpha / (len(names) * (len(names) - 1) / 2)
    evidence = []
    for j, other in enumerate(names):
        if j == i:
            continue
        k, m = int(only[i, j]), int(only[j, i])
        e = float(np.exp(log_e_value(k, k + m, prior)))
        evidence.append(
            PairEvidence(
                leader, other, len(common), k, m, e, need, confidence_sequence(k, k + m, level)
            )
        )
    evidence.sort(key=lambda ev: (ev.e_value, ev.other))
    return SequentialVerdict(rates, tasks, chosen, leader, tuple(evidence), group)


#: Largest study size :func:`tasks_to_decide` searches [tasks].
MAX_TASKS = 10_000_000


def tasks_to_decide(
    evidence: PairEvidence, prior: float = PRIOR, most: int = MAX_TASKS
) -> int | None:
    """About how many tasks in all the claim of ``evidence`` needs, if its rates hold.

    With ``n`` tasks so far, ``b`` leader-only and ``c`` other-only tasks, ``N`` tasks give
    about ``round(bN/n)`` and ``round(cN/n)``; the estimate is the smallest ``N ≥ n`` whose
    e-value then reaches the threshold (doubling, then bisection). An estimate from few tasks
    ("about"), not a promise. None when ``b ≤ c`` (no direction) or above ``most``.
    """
    b, c, n = evidence.leader_only, evidence.other_only, evidence.tasks
    if n <= 0 or b <= c:
        return None
    bound = math.log(evidence.needed)

    def enough(total: int) -> bool:
        wins, losses = round(b * total / n), round(c * total / n)
        return bool(log_e_value(wins, wins + losses, prior) >= bound)

    return smallest_enough(enough, n, n, most)
