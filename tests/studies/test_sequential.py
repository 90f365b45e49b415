"""The anytime-valid success decision (issue 36): its e-process, its intervals, its error rate."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad
from scipy.special import betaln
from scipy.stats import beta

from otmm_qp.studies.decide_simulation import looks, simulate
from otmm_qp.studies.sequential import (
    PRIOR,
    confidence_sequence,
    discordant_counts,
    fixed_sample_pick,
    log_e_value,
    pick,
    pick_from_counts,
    threshold,
)
from otmm_qp.studies.statistics import paired_ranking, paired_success


def _quadrature(wins: int, discordant: int) -> float:
    def integrand(theta: float) -> float:
        ratio = theta**wins * (1 - theta) ** (discordant - wins) / 0.5**discordant
        return 2.0 * ratio * float(beta.pdf(theta, PRIOR, PRIOR))

    return float(quad(integrand, 0.5, 1.0, epsabs=0.0, epsrel=1e-10)[0])


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 60).flatmap(lambda n: st.tuples(st.integers(0, n), st.just(n))))
def test_the_e_value_is_the_one_sided_mixture(counts: tuple[int, int]) -> None:
    wins, discordant = counts
    direct = _quadrature(wins, discordant)
    assert float(np.exp(log_e_value(wins, discordant))) == pytest.approx(direct, rel=1e-7)


@pytest.mark.parametrize("share", [0.5, 0.45, 0.3, 0.0])
def test_the_e_value_is_a_supermartingale_when_a_is_not_better(share: float) -> None:
    # one more discordant task: A's with probability share ≤ 1/2; E[E_{n+1}] ≤ E_n (= at 1/2)
    for n in range(0, 40):
        for k in range(n + 1):
            now = math.exp(float(log_e_value(k, n)))
            up, down = (math.exp(float(log_e_value(j, n + 1))) for j in (k + 1, k))
            expected = share * up + (1 - share) * down
            assert expected <= now * (1 + 1e-9)
            if share == 0.5:
                assert expected == pytest.approx(now, rel=1e-9)


@settings(max_examples=30, deadline=None)
@given(
    st.integers(1, 80).flatmap(lambda n: st.tuples(st.integers(0, n), st.just(n))),
    st.sampled_from([0.05, 0.01, 0.001]),
)
def test_the_confidence_sequence_inverts_the_mixture(counts: tuple[int, int], alpha: float) -> None:
    k, n = counts
    low, high = confidence_sequence(k, n, alpha)
    assert 0.0 <= low <= k / n <= high <= 1.0

    def log_ratio(theta: float) -> float:  # log of the two-sided mixture over θ's likelihood
        mixture = float(betaln(k + PRIOR, n - k + PRIOR) - betaln(PRIOR, PRIOR))
        return mixture - k * math.log(theta) - (n - k) * math.log1p(-theta)

    for edge, end in ((low, 0.0), (high, 1.0)):
        if edge != end:  # an inner edge: the ratio reaches 1/α there
            assert log_ratio(edge) == pytest.approx(math.log(1 / alpha), abs=1e-6)
    narrower = confidence_sequence(k, n, alpha * 5)
    assert low <= narrower[0] and narrower[1] <= high


@settings(max_examples=60, deadline=None)
@given(st.integers(2, 4), st.integers(1, 40), st.integers(0, 2**32 - 1))
def test_the_baseline_is_the_former_rule(rows: int, tasks: int, seed: int) -> None:
    # the former decide.decided: McNemar (Holm) ranking, one row beating every other
    rng = np.random.default_rng(seed)
    success = rng.random((tasks, rows)) < rng.random(rows)
    names = [f"r{i}" for i in range(rows)]
    flags = {n: {t: bool(success[t, i]) for t in range(tasks)} for i, n in enumerate(names)}
    rates = {n: sum(f.values()) / tasks for n, f in flags.items()}
    ranking = paired_ranking(rates, paired_success(flags), higher_is_better=True)
    top = [r for r in ranking if r.rank == 1]
    former = (
        top[0].name
        if len(top) == 1 and all(top[0].name in r.beaten_by for r in ranking if r is not top[0])
        else None
    )
    chosen = fixed_sample_pick(discordant_counts(success))
    assert (names[chosen] if chosen is not None else None) == former


@settings(max_examples=40, deadline=None)
@given(st.integers(2, 4), st.integers(1, 300), st.integers(0, 2**32 - 1))
def test_a_pick_beats_every_other_row_and_ignores_the_order(
    rows: int, tasks: int, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    success = rng.random((tasks, rows)) < rng.random(rows)
    only = discordant_counts(success)
    chosen = pick_from_counts(only)
    if chosen is not None:
        for j in range(rows):
            if j != chosen:
                e = float(log_e_value(only[chosen, j], only[chosen, j] + only[j, chosen]))
                assert e >= math.log(threshold(rows))
    order = rng.permutation(rows)
    again = pick_from_counts(discordant_counts(success[:, order]))
    assert (order[again] if again is not None else None) == chosen


def test_pick_reports_the_evidence_of_the_leader() -> None:
    flags = {
        "a": dict.fromkeys(range(80), True),
        "b": {t: t < 20 for t in range(80)},
        "c": {t: t < 60 for t in range(80)},
    }
    verdict = pick(flags)
    assert verdict.pick == "a" and verdict.leader == "a"
    closest = verdict.evidence[0]  # the smallest e-value first: c
    assert (closest.other, closest.leader_only, closest.other_only) == ("c", 20, 0)
    assert closest.beaten and closest.p_anytime < 0.05 and closest.share[0] > 0.5
    assert verdict.group == ("a",)
    tied = pick({"x": dict.fromkeys(range(5), True), "y": dict.fromkeys(range(5), True)})
    assert not tied.decided and tied.evidence[0].p_anytime == 1.0 and tied.group == ()
    # two rows that differ on one task both beat a third: a group, not a pick
    pair = pick({"a": flags["a"], "b": {t: t != 3 for t in range(80)}, "c": flags["b"]})
    assert pair.pick is None and pair.group == ("a", "b")


def test_under_equal_rates_the_anytime_rule_keeps_alpha_and_the_former_did_not() -> None:
    schedule = looks(200, 10)  # a look after every batch of 10, budget 200
    anytime = simulate(pick_from_counts, (0.6, 0.6), schedule, 300, seed=1)
    former = simulate(fixed_sample_pick, (0.6, 0.6), schedule, 300, seed=1)
    assert anytime.false_rate <= 0.05 and anytime.interval(anytime.false)[0] < 0.05
    assert former.interval(former.false)[0] > 0.05  # the inflation, beyond Monte-Carlo error
    better = simulate(pick_from_counts, (0.5, 0.7), looks(600, 60), 100, seed=2)
    assert better.false == 0 and better.power > 0.9 and better.mean_tasks < 600
