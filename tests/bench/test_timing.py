"""The bench's timing schedule and statistics (no timing is asserted, only what is run when)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from otmm_qp.bench.floor import FLOOR
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
    assert checks["otmm+qp (daqp, persistent) ≤ 0.38 × pink (daqp)"] is False  # 45 > 38
    assert checks["otmm+qp (daqp, persistent, QP every step) ≤ 0.5 × pink (daqp)"] is False  # 61
    assert checks["otmm+pinv ≤ 0.3 × pink (daqp)"] is False  # 36 > 30
    assert not any("floor" in target for target in checks)  # no floor timed: no floor target

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


def test_floor_ratio_and_target() -> None:
    """Each row's ratio to the floor; otmm+pinv held to 4 × the floor of the same run."""
    times = {
        FLOOR: np.array([10.0, 12.0, 11.0]),
        "pink (daqp)": np.array([150.0]),
        "otmm+pinv": np.array([44.0, 45.0, 40.0]),
        "otmm+qp (osqp, persistent)": np.array([74.0]),
    }
    rows = {row["pipeline"]: row for row in summarise(times)}
    assert rows[FLOOR]["ratio_to_floor"] == 1.0 and rows[FLOOR]["library"] == "floor"
    assert rows["otmm+pinv"]["ratio_to_floor"] == pytest.approx(4.0)
    assert rows["pink (daqp)"]["ratio_to_floor"] == pytest.approx(150.0 / 11.0)
    checks = {c["target"]: c for c in check_targets(list(rows.values()))}
    assert checks[f"otmm+pinv ≤ 4 × {FLOOR}"]["met"] is True  # 44 = 4 × 11
    assert checks[f"otmm+pinv ≤ 4 × {FLOOR}"]["limit_us"] == pytest.approx(44.0)
    assert checks["otmm+pinv ≤ 0.3 × pink (daqp)"]["met"] is True  # 44 < 45
    assert checks["otmm+qp (osqp, persistent) ≤ 0.5 × pink (daqp)"]["met"] is True  # 74 < 75
    times[FLOOR] = np.array([10.9])
    checks = {c["target"]: c["met"] for c in check_targets(summarise(times))}
    assert checks[f"otmm+pinv ≤ 4 × {FLOOR}"] is False  # 44 > 43.6
