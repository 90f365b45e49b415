"""The one metric table: every reader indexes it, and it matches what compute_metrics returns.

Adding a metric is one ``Metric`` row plus its value in ``compute_metrics``: the first test
fails until both are there, the second shows a row reaching every reader.
"""

from __future__ import annotations

import numpy as np
import pytest

from otmm_qp.controller import Controller
from otmm_qp.exceptions import ConfigError
from otmm_qp.metrics import METRIC_NAMES, METRICS, Metric, compute_metrics, metric
from otmm_qp.output.pareto import OBJECTIVES
from otmm_qp.output.report import RANKED_METRICS, REPORT_COLUMNS
from otmm_qp.output.summary import MARKDOWN_COLUMNS, summary_row
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.simulation import Episode, simulate
from otmm_qp.trajectories.circle import CircleTrajectory
from otmm_qp_controllers.pinv import PseudoInverseBackend


def _run() -> dict[str, object]:
    robot = PlanarArm([1.0, 0.8])
    q0 = np.array([0.927, -2.5])
    trajectory = CircleTrajectory(robot.forward(q0), [1.2, 0.0], 0.6, 10.0)
    result = simulate(
        Episode(robot, trajectory, q0, 0.02, 0.4), Controller("p", [], PseudoInverseBackend())
    )
    return compute_metrics(result)


def test_compute_metrics_returns_exactly_the_table() -> None:
    assert sorted(_run()) == sorted(m.name for m in METRICS)
    assert METRIC_NAMES == tuple(m.name for m in METRICS)  # the stored column order
    assert len({m.name for m in METRICS}) == len(METRICS)


def test_every_reader_indexes_the_table() -> None:
    for name, heading, fmt in (*MARKDOWN_COLUMNS, *REPORT_COLUMNS):
        row = metric(name)
        assert (heading, fmt) == (row.heading, row.fmt)
    # the report marks the lowest value best and ranks by them; Pareto minimises
    assert all(metric(name).lower_is_better for name, _, _ in REPORT_COLUMNS)
    assert all(metric(name).lower_is_better for name in (*RANKED_METRICS, *OBJECTIVES))
    assert OBJECTIVES == ("max_error_window", "max_joint_speed", "max_jump")


def test_a_row_formats_values_and_unknown_names_are_refused() -> None:
    row = Metric("max_error", "max err", "m", ".2e")
    assert row.heading == "max err [m]" and format(1.234e-3, row.fmt) == "1.23e-03"
    assert Metric("steps", "steps", "").heading == "steps"
    with pytest.raises(ConfigError, match="unknown metric 'nope'; known: max_error, "):
        metric("nope")


def test_the_summary_row_has_every_metric_column() -> None:
    row = summary_row({"experiment": "E"}, _run(), None)
    assert [k for k in row if k in METRIC_NAMES] == list(METRIC_NAMES)
