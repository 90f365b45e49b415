"""The report's statistics fast paths give the values of the plain computations bit for bit.

* bootstrap medians from the cached sorted resample indices = ``np.median`` of
  ``default_rng(seed).choice(data, ...)`` (sizes odd and even, ties, one value, large blocks);
* ``average_ranks`` = ``scipy.stats.rankdata`` (ties, signed zeros);
* ``Rows.select`` from its index = the scan, in row order, after the rows grow too.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy import stats

from otmm_qp.studies import statistics as S
from otmm_qp.studies.rows import Rows


def _plain_medians(data: np.ndarray, seed: int, resamples: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    block = max(1, 2_000_000 // max(1, data.size))
    medians = np.empty(resamples)
    for start in range(0, resamples, block):
        count = min(block, resamples - start)
        samples = rng.choice(data, size=(count, data.size), replace=True)
        medians[start : start + count] = np.median(samples, axis=1)
    return medians


@pytest.mark.parametrize("size", [1, 2, 3, 10, 39, 40, 1001, 2500])
@pytest.mark.parametrize("seed", [0, 7])
def test_bootstrap_medians_are_the_plain_ones(size: int, seed: int) -> None:
    rng = np.random.default_rng(size)
    data = np.sort(np.round(rng.normal(size=size), 1))  # ties
    for resamples in (2000, 3):
        fast = S._resampled_medians(data, seed, resamples)
        assert np.array_equal(fast, _plain_medians(data, seed, resamples))
    interval = S.bootstrap_interval(data[::-1], seed=seed)  # order does not matter
    assert interval == S.bootstrap_interval(data, seed=seed)


@given(st.lists(st.sampled_from([-2.0, -0.0, 0.0, 0.5, 1.0, 1.0, 3.25]), min_size=1, max_size=30))
def test_average_ranks_are_scipys(values: list[float]) -> None:
    x = np.array(values)
    assert np.array_equal(S.average_ranks(x), stats.rankdata(x))


def test_select_from_its_index_is_the_scan() -> None:
    rng = np.random.default_rng(1)
    rows = [
        {"robot": str(rng.integers(3)), "controller": str(rng.integers(4)), "n": int(i)}
        for i in range(200)
    ]
    table = Rows(rows)

    def scan(**equal: object) -> list[dict]:
        return [r for r in table.rows if all(r.get(k) == v for k, v in equal.items())]

    for robot in "0123":
        for controller in ("0", "3", "9"):
            assert table.select(robot=robot, controller=controller) == scan(
                robot=robot, controller=controller
            )
        assert table.select(robot=robot) == scan(robot=robot)
    table.rows.append({"robot": "1", "controller": "0", "n": 200})  # the index follows
    assert table.select(robot="1")[-1]["n"] == 200
    table.rows.append({"robot": ["unhashable"], "controller": "0"})
    assert table.select(robot="1") == scan(robot="1")
    assert table.select(robot=["unhashable"]) == scan(robot=["unhashable"])
