"""Piecewise trajectories switch at the step the user means (integer time comparison)."""

from __future__ import annotations

from decimal import Decimal

import numpy as np
import pytest
import yaml

from otmm_qp.config.load import parse_config
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.runner import run_suite
from otmm_qp.trajectories.held_targets import HeldTargetsTrajectory
from otmm_qp.trajectories.time_grid import piece_index, start_ticks
from tests.controllers.test_strategy_backends import reference_jparse


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


PANDA_LINE = """
version: 2
name: panda_line
dt: 0.02
loop_modes: [clik]
clik_gain: 5.0
experiments:
  - name: line
    robot: {type: pinocchio, name: panda, task: position}
    q0: Q0
    trajectory: {type: held_targets, targets: TARGETS, hold: HOLD}
    duration: 5.0
    controllers:
      - {name: J-PARSE, backend: {type: jparse}}
      - {name: DLS, backend: {type: dls, damping: 0.05}}
"""


@pytest.mark.parametrize("hold", ["0.1", "0.0999999"])
def test_the_jparse_authors_panda_line_loop_is_reproduced_with_either_hold(hold: str) -> None:
    """The authors' loop, written out: target ``i = k // 5`` at step ``k``, q ← q + dt·q̇.

    50 targets on a line from the Panda's start toward [0.95, 0, 0.45] (past its reach), each
    held ``hold`` s at dt = 0.02 s, ``q̇ = J-PARSE(J)·K(X_i − p(q))`` (matrix form, numpy's
    pinv) or DLS. ``hold: 0.1`` switched 30 of 50 targets a step late under the float sum of
    holds (J-PARSE's peak speed +11 %); ``0.0999999`` (below every switch) never did. Both
    must now give the same loop.
    """
    arm = PinocchioArm(name="panda", task="position")
    q0 = [0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8]
    start = arm.forward(arm.configuration(np.array(q0)))
    end = np.array([0.95, 0.0, 0.45])
    targets = [[float(v) for v in start + (end - start) * (i + 1) / 50] for i in range(50)]
    text = PANDA_LINE.replace("Q0", str(q0)).replace("TARGETS", str(targets))
    suite = parse_config(yaml.safe_load(text.replace("HOLD", hold)))
    records = {r.identity["controller"]: r.result for r in run_suite(suite, None).records}
    solvers = {
        "J-PARSE": lambda J, v: reference_jparse(J, v, 0.1, 1.0),
        "DLS": lambda J, v: J.T @ np.linalg.solve(J @ J.T + 0.05**2 * np.eye(3), v),
    }
    for name, solve in solvers.items():
        q = arm.configuration(np.array(q0))
        expected = [q]
        for k in range(len(records[name].t) - 1):
            error = np.asarray(targets[min(k // 5, 49)]) - arm.forward(q)
            q = q + 0.02 * solve(arm.jacobian(q), 5.0 * error)
            expected.append(q)
        np.testing.assert_allclose(records[name].q, np.array(expected), rtol=0, atol=1e-9)
