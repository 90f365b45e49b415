"""Piecewise trajectories switch at the step the user means (integer time comparison)."""

from __future__ import annotations

from decimal import Decimal

import numpy as np
import pytest

from otmm_qp.trajectories.held_targets import HeldTargetsTrajectory
from otmm_qp.trajectories.time_grid import piece_index, start_ticks


def _targets(count: int) -> list[list[float]]:
    return [[1.0 + 0.01 * i, 0.0] for i in range(count)]


#: ``(hold, dt)`` pairs [s] (decimal text) whose ratio is a whole number of steps.
CASES = [
    (hold, dt)
    for hold in ("0.1", "0.3", "0.07", "0.15", "0.25", "1.1")
    for dt in ("0.02", "0.01", "0.005", "0.001")
    if Decimal(hold) % Decimal(dt) == 0
]


@pytest.mark.parametrize(("hold", "dt"), CASES)
def test_held_targets_switch_every_hold_over_dt_steps(hold: str, dt: str) -> None:
    """With ``hold = m·dt`` in decimal, target ``i`` is held on steps ``[i·m, (i+1)·m)``."""
    m, count = int(Decimal(hold) / Decimal(dt)), 50
    trajectory = HeldTargetsTrajectory(np.zeros(2), _targets(count), hold=float(hold))
    times = np.arange(m * count) * float(dt)  # t_k = k·dt, as the loop samples
    held = [trajectory.index(float(t)) for t in times]
    assert held == [k // m for k in range(m * count)]
    targets = np.array([trajectory.sample(float(t))[0] for t in times])
    expected = np.array(_targets(count))[np.arange(m * count) // m, 0]
    np.testing.assert_array_equal(targets[:, 0], expected)


def test_the_issue_case_switches_on_time() -> None:
    """``hold: 0.1`` at dt = 0.02: the float sum put 30 of 50 switches one step late."""
    trajectory = HeldTargetsTrajectory(np.zeros(2), _targets(50), hold=0.1)
    assert trajectory.starts[3] > 15 * 0.02  # 0.30000000000000004 > 0.3: the trap
    assert trajectory.index(15 * 0.02) == 3


def test_per_target_holds_and_the_ends() -> None:
    trajectory = HeldTargetsTrajectory(np.zeros(2), _targets(3), hold=[0.1, 0.2, 0.3])
    assert [trajectory.index(t) for t in (-1.0, 0.0, 0.0999, 0.1, 0.3, 5.0)] == [0, 0, 0, 1, 2, 2]


def test_piece_index_is_exact_for_huge_durations() -> None:
    starts = start_ticks([1e300, 1.0])
    assert piece_index(starts, 1.0) == 0 and piece_index(starts, 1e301) == 1
