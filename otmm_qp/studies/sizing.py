r"""How many tasks a success verdict would need, from the discordant pairs observed so far.

A group's verdict is *decided* when one row beats every other on success by the exact McNemar
test (Holm over the table's pairs). The test only sees the *discordant* tasks, where exactly
one of the two rows succeeds. With ``n`` tasks so far, ``b`` tasks where the leader alone
succeeds and ``c`` where the other does, the observed rates are

.. math:: d = (b + c)/n \quad(\text{discordant share}), \qquad
          \pi = b/(b + c) \quad(\text{leader's share of them}).

If those rates held, ``N`` tasks give about ``D = \mathrm{round}(dN)`` discordant tasks, and
the test rejects at level ``α'`` when the leader alone succeeds on at least ``k*(D)`` of them,
the smallest ``k`` with ``2\,P(X \ge k \mid X \sim \mathrm{Bin}(D, ½)) \le α'``. Its power is
``P(Y \ge k^*(D))``, ``Y \sim \mathrm{Bin}(D, π)``. :func:`tasks_needed` returns the smallest
``N`` (searched by doubling then bisection) whose power reaches ``power`` (0.8) at
``α' = α/m``, ``m`` the number of pairs Holm corrects over (its first, strictest step, so the
estimate errs on the side of more tasks). It is an estimate from few tasks ("about"), not a
promise: the rates themselves are uncertain. When ``π ≤ ½`` the leader is not ahead on the
tasks that tell them apart and no number of tasks is expected to separate them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from scipy.stats import binom

from otmm_qp.studies.statistics import PairedRates

__all__ = ["decision_advice", "mcnemar_power", "tasks_needed"]

#: Largest study size searched [tasks].
MAX_TASKS = 10_000_000


def _critical(discordant: int, alpha: float) -> int | None:
    """Smallest leader-alone count the two-sided exact test rejects at ``alpha`` (None: none)."""
    if discordant <= 0:
        return None
    low, high = (discordant + 1) // 2, discordant
    if 2.0 * float(binom.sf(high - 1, discordant, 0.5)) > alpha:
        return None
    while low < high:  # the tail probability falls as k grows
        middle = (low + high) // 2
        if 2.0 * float(binom.sf(middle - 1, discordant, 0.5)) <= alpha:
            high = middle
        else:
            low = middle + 1
    return low


def mcnemar_power(tasks: int, discordant_share: float, leader_share: float, alpha: float) -> float:
    """Power of the exact McNemar test on ``tasks`` tasks at the given rates (see the module)."""
    discordant = round(discordant_share * tasks)
    k = _critical(discordant, alpha)
    return 0.0 if k is None else float(binom.sf(k - 1, discordant, leader_share))


def tasks_needed(
    leader_only: int,
    other_only: int,
    tasks: int,
    comparisons: int,
    alpha: float = 0.05,
    power: float = 0.8,
) -> int | None:
    """About how many tasks in all would separate the leader from the other row (see module).

    Args:
        leader_only: Tasks where the leader alone succeeds (``b``).
        other_only: Tasks where the other row alone succeeds (``c``).
        tasks: Tasks both rows ran so far (``n`` ≥ b + c).
        comparisons: Pairs Holm corrects over (``m`` ≥ 1).
        alpha: Family-wise level.
        power: Wanted power.

    Returns:
        The smallest such number of tasks (≤ :data:`MAX_TASKS`), or None when the observed
        rates give no direction (``b ≤ c``) or no size up to :data:`MAX_TASKS` suffices.
    """
    if tasks <= 0 or leader_only <= other_only or leader_only + other_only > tasks:
        return None
    share = (leader_only + other_only) / tasks
    ahead = leader_only / (leader_only + other_only)
    level = alpha / max(comparisons, 1)

    def enough(n: int) -> bool:
        return mcnemar_power(n, share, ahead, level) >= power

    return smallest_enough(enough, 1, max(tasks, 1), MAX_TASKS)


def smallest_enough(enough: Callable[[int], bool], low: int, start: int, most: int) -> int | None:
    """The smallest ``n ≥ low`` with ``enough(n)``, for ``enough`` monotone in ``n``.

    Doubling from ``start`` (≥ ``low``) up to ``most`` finds a size that suffices, then
    bisection on ``[low, that size]``. None when ``most`` does not suffice.
    """
    high = start
    while not enough(high):
        if high >= most:
            return None
        high = min(2 * high, most)
    while low < high:
        middle = (low + high) // 2
        if enough(middle):
            high = middle
        else:
            low = middle + 1
    return low


def decision_advice(leader: str, tests: Sequence[PairedRates]) -> str:
    """One clause for an undecided group: the tasks ``leader`` would need to beat every row.

    The binding row is the one needing the most tasks (or one whose observed rates give no
    direction, which is said instead). ``tests`` are the table's McNemar tests; Holm corrects
    over all of them (:func:`tasks_needed`'s ``comparisons``).
    """
    needs: list[tuple[float, str, int, int, int, int | None]] = []
    tied: list[str] = []
    for test in tests:
        if leader not in (test.a, test.b):
            continue
        first = test.a == leader
        mine, theirs = (test.a_only, test.b_only) if first else (test.b_only, test.a_only)
        other = test.b if first else test.a
        if mine + theirs == 0:  # the same successes: no number of tasks tells them apart
            tied.append(other)
            continue
        needed = tasks_needed(mine, theirs, test.pairs, len(tests))
        key = math.inf if needed is None else float(needed)
        needs.append((key, other, mine, theirs, test.pairs, needed))
    ties = (
        f"{', '.join([leader, *sorted(tied)])} succeed on the same tasks (tied: more tasks "
        "would not separate them)"
        if tied
        else ""
    )
    if not needs:
        return ties or f"{leader} has no paired test"
    _, other, mine, theirs, pairs, needed = max(needs, key=lambda item: (item[0], item[1]))
    who = f"{leader} (or its ties)" if tied else leader
    where = (
        f"against {other}, {leader} alone succeeds on {mine} tasks and {other} alone on {theirs}"
    )
    if needed is None:
        text = (
            f"{where}: these rates do not favour {leader}, so more tasks are not expected to decide"
        )
    else:
        level = f"Holm level 0.05/{len(tests)}" if len(tests) > 1 else "level 0.05"
        text = (
            f"a decision for {who} needs about {_round(needed)} tasks of this kind "
            f"({_round(max(needed - pairs, 0))} more; {where}; exact McNemar at {level}, "
            "80 % power, if these rates hold)"
        )
    return f"{ties}; {text}" if ties else text


def _round(count: int) -> str:
    """A task count to two significant digits (it is an estimate), e.g. ``140``, ``1,300``."""
    if count < 100:
        return str(count)
    digits = int(math.floor(math.log10(count))) - 1
    return f"{round(count, -digits):,}"
