"""studies.sizing: tasks a success verdict would need, from the observed discordant pairs."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.stats import binomtest

from otmm_qp.studies.sizing import _round, decision_advice, mcnemar_power, tasks_needed
from otmm_qp.studies.statistics import PairedRates


def test_all_discordant_for_the_leader_needs_the_smallest_exact_rejection() -> None:
    # 2 of 3 tasks discordant, all for the leader; level 0.05/15: 2·2^-D <= 0.00333 needs D = 10,
    # and D = round(2/3 N) = 10 first at N = 15 (power 1 when the leader wins every discordant)
    assert tasks_needed(2, 0, 3, 15) == 15
    assert tasks_needed(2, 0, 3, 1) == 9  # level 0.05: D = 6 (2/64 = 0.031), round(2/3·9) = 6


@pytest.mark.parametrize(("b", "c", "n"), [(0, 0, 10), (3, 3, 10), (2, 5, 10), (0, 4, 4)])
def test_no_direction_no_size(b: int, c: int, n: int) -> None:
    assert tasks_needed(b, c, n, 3) is None


@given(
    b=st.integers(1, 40),
    c=st.integers(0, 40),
    extra=st.integers(0, 60),
    m=st.integers(1, 45),
)
def test_the_size_reaches_the_power_and_one_task_less_does_not(
    b: int, c: int, extra: int, m: int
) -> None:
    n = b + c + extra
    needed = tasks_needed(b, c, n, m)
    if b <= c:
        assert needed is None
        return
    assert needed is not None
    share, ahead, level = (b + c) / n, b / (b + c), 0.05 / m
    assert mcnemar_power(needed, share, ahead, level) >= 0.8
    assert (
        needed == 1
        or mcnemar_power(needed - 1, share, ahead, level) < 0.8
        or (
            # the power is a saw-tooth in N (D is rounded): bisection may land past a tooth
            mcnemar_power(needed - 1, share, ahead, level) >= 0.8
            and any(mcnemar_power(k, share, ahead, level) < 0.8 for k in range(1, needed - 1))
        )
    )


def test_size_matches_a_simulation_of_studies_at_those_rates() -> None:
    """Draw studies of the estimated size at the observed rates: about 80 % reject."""
    b, c, n, m = 9, 3, 30, 6
    needed = tasks_needed(b, c, n, m)
    assert needed is not None and needed > n
    rng = np.random.default_rng(7)
    probabilities = [b / n, c / n, 1 - (b + c) / n]
    rejections = 0
    for _ in range(400):
        leader, other, _ = rng.multinomial(needed, probabilities)
        p = binomtest(int(leader), int(leader + other), 0.5).pvalue if leader + other else 1.0
        rejections += p <= 0.05 / m
    assert 0.65 <= rejections / 400 <= 0.95


def _test(a: str, b: str, a_only: int, b_only: int, pairs: int = 20) -> PairedRates:
    return PairedRates(a, b, pairs, a_only, b_only, pairs - a_only - b_only, 1.0)


def test_advice_names_the_binding_row_and_the_ties() -> None:
    tests = [
        _test("qp", "qp2", 0, 0),
        _test("qp", "dls", 8, 1),
        _test("sns", "qp", 2, 5),
        _test("dls", "qp2", 1, 8),
        _test("sns", "dls", 3, 3),
        _test("sns", "qp2", 2, 5),
    ]
    text = decision_advice("qp", tests)
    assert text.startswith("qp, qp2 succeed on the same tasks (tied")
    needed = tasks_needed(5, 2, 20, 6)  # sns is the binding row: closer than dls
    assert needed is not None and f"about {_round(needed)} tasks" in text and "against sns" in text
    assert decision_advice("qp", tests[:1]).startswith("qp, qp2 succeed on the same tasks")
    assert "not expected to decide" in decision_advice("sns", tests)
