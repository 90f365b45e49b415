"""Simulated ``decide`` studies: synthetic paired successes through a decision rule.

The rule looks as the batch loop looks.

Each simulated study draws ``budget`` tasks; on each task row ``i`` succeeds with probability
``rates[i]``, independently of the other rows (``shared = 0``) or, with probability
``shared``, through one uniform draw ``u`` common to every row (``u < rates[i]``: a task
hard for one row is hard for the others, fewer discordant tasks). After the first ``t`` tasks
of each look ``t`` in :func:`looks` the rule sees the paired counts of those tasks
(:func:`~otmm_qp.studies.sequential.discordant_counts`) — exactly what a study's loop gives
it — and the study stops at the first look with a decision. A decision is *false* when the
named row's rate is not strictly above every other's.

Used by ``benchmarks/bench_decide.py`` (thousands of studies, the numbers in docs/studies.md)
and ``tests/studies/test_sequential.py`` (fewer).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.stats import beta

#: A decision rule on paired counts ``only[i, j]`` (the row it names, or None).
Rule = Callable[[NDArray[np.int64]], int | None]


def looks(budget: int, batch: int) -> list[int]:
    """The task counts a study with ``decide: {budget_tasks: budget, batch: batch}`` judges at."""
    step = min(batch, budget)
    return [min(k * step, budget) for k in range(1, math.ceil(budget / step) + 1)]


def draw(
    rng: np.random.Generator, budget: int, rates: Sequence[float], shared: float = 0.0
) -> NDArray[np.bool_]:
    """Success flags of one study, shape ``(budget, rows)`` (see the module)."""
    p = np.asarray(rates, dtype=float)
    independent = rng.random((budget, p.size)) < p
    common = rng.random((budget, 1)) < p
    use = rng.random((budget, 1)) < shared
    return np.where(use, common, independent)


@dataclass(frozen=True)
class Summary:
    """What a rule did over many simulated studies.

    Attributes:
        studies: Simulated studies.
        decisions: Studies that named a row.
        false: Of those, decisions naming a row not strictly better than every other.
        right: Decisions naming the row strictly better than every other (if there is one).
        mean_tasks: Mean tasks per study when it stopped (the budget when undecided).
    """

    studies: int
    decisions: int
    false: int
    right: int
    mean_tasks: float

    @property
    def false_rate(self) -> float:
        """False decisions per study."""
        return self.false / self.studies

    @property
    def power(self) -> float:
        """Right decisions per study."""
        return self.right / self.studies

    def interval(self, count: int, confidence: float = 0.95) -> tuple[float, float]:
        """Clopper-Pearson interval of ``count`` per study (Monte-Carlo error of a rate)."""
        tail = (1.0 - confidence) / 2.0
        low = 0.0 if count == 0 else float(beta.ppf(tail, count, self.studies - count + 1))
        high = (
            1.0 if count == self.studies else float(beta.isf(tail, count + 1, self.studies - count))
        )
        return low, high


def simulate(
    rule: Rule,
    rates: Sequence[float],
    schedule: Sequence[int],
    studies: int,
    seed: int = 0,
    shared: float = 0.0,
) -> Summary:
    """Run ``studies`` simulated studies of ``rule`` looking at ``schedule`` (see the module).

    Args:
        rule: The decision rule on paired counts.
        rates: Each row's true success rate.
        schedule: Increasing task counts of the looks; the last is the budget.
        studies: Simulated studies.
        seed: Seed of the draws (the same draws for every rule given the same seed).
        shared: Share of tasks decided by one common draw (correlated rows).
    """
    rng = np.random.default_rng(seed)
    budget = schedule[-1]
    p = np.asarray(rates, dtype=float)
    best = [i for i in range(p.size) if all(p[i] > p[j] for j in range(p.size) if j != i)]
    decisions = false = right = 0
    spent = 0
    for _ in range(studies):
        flags = draw(rng, budget, rates, shared).astype(np.int64)
        # only[t, i, j]: tasks among the first t where i alone succeeds (t = 0..budget)
        steps = flags[:, :, None] * (1 - flags[:, None, :])
        only = np.concatenate([np.zeros((1, p.size, p.size), np.int64), np.cumsum(steps, 0)])
        stop = budget
        for tasks in schedule:
            named = rule(only[tasks])
            if named is not None:
                decisions += 1
                right += named in best
                false += named not in best
                stop = tasks
                break
        spent += stop
    return Summary(studies, decisions, false, right, spent / studies)
