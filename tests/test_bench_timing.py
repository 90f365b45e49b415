"""The bench's timing schedule and statistics (no timing is asserted, only what is run when)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from otmm_qp.bench.timing import check_targets, summarise, time_pipelines


def test_each_pipeline_sees_its_states_in_order_in_interleaved_blocks() -> None:
    calls: list[tuple[str, int]] = []

    def pipeline(name: str) -> Callable[[int], None]:
        return lambda k: calls.append((name, k))

    names = ["a", "b", "c"]
    times = time_pipelines({n: pipeline(n) for n in names}, steps=10, rounds=2, block=4)
    assert all(t.shape == (20,) and (t >= 0.0).all() for t in times.values())
    warm_up, timed = calls[:30], calls[30:]
    assert [k for _, k in warm_up] == list(range(10)) * 3
    for name in names:
        ks = [k for n, k in timed if n == name]
        assert ks == list(range(10)) * 2  # in order, every round
    # Per round, blocks of 4, 4 and 2 consecutive states; each pipeline runs a whole block.
    orders = []
    position = 0
    for _ in range(2):
        for block in ([0, 1, 2, 3], [4, 5, 6, 7], [8, 9]):
            order = []
            for _ in names:
                chunk = timed[position : position + len(block)]
                position += len(block)
                assert len({n for n, _ in chunk}) == 1 and [k for _, k in chunk] == block
                order.append(chunk[0][0])
            assert sorted(order) == names
            orders.append(tuple(order))
    assert position == len(timed)
    assert len(set(orders)) > 1  # a fresh random order per block


def test_ratios_and_targets_from_medians() -> None:
    times = {
        "pink (daqp)": np.array([100.0, 110.0, 90.0]),
        "otmm+qp (daqp, persistent)": np.array([40.0, 50.0, 45.0]),
        "otmm+qp (daqp, persistent, QP every step)": np.array([70.0, 61.0, 59.0]),
        "otmm+pinv": np.array([36.0, 36.0, 36.0]),
    }
    rows = {row["pipeline"]: row for row in summarise(times)}
    assert rows["otmm+qp (daqp, persistent)"]["ratio_to_pink_daqp"] == pytest.approx(0.45)
    checks = {c["target"]: c["met"] for c in check_targets(list(rows.values()))}
    assert checks["otmm+qp (daqp, persistent) ≤ 0.5 × pink (daqp)"] is True
    assert checks["otmm+qp (daqp, persistent, QP every step) ≤ 0.6 × pink (daqp)"] is False  # 61
    assert checks["otmm+pinv ≤ 0.35 × pink (daqp)"] is False  # 36 > 35

    # each qp row is paired with pink on the same solver, by the solver its label names
    paired = {
        "pink (proxqp)": np.array([200.0]),
        "qp (proxsuite, persistent)": np.array([150.0]),
        "qp (proxqp, qpsolvers)": np.array([250.0]),
    }
    checks = {c["target"]: c["met"] for c in check_targets(summarise({**times, **paired}))}
    assert checks["qp (proxsuite, persistent) ≤ pink (proxqp)"] is True
    assert checks["qp (proxqp, qpsolvers) ≤ pink (proxqp)"] is False
    assert not any(t.startswith(("pink", "mink", "otmm+pinv ≤ pink")) for t in checks)
