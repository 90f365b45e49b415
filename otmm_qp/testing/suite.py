"""The conformance tests collected by ``pytest --otmm-controller NAME``.

One test per (controller, scenario, check); see :mod:`otmm_qp.testing.conformance`.
"""

from __future__ import annotations

import pytest

from otmm_qp.runner.run import RunRecord
from otmm_qp.testing import conformance


def test_conformance(
    otmm_run: RunRecord, otmm_scenario: conformance.Scenario, otmm_check: str
) -> None:
    """The run passes ``otmm_check`` (finite, position_limits, joint_speed, tracking)."""
    verdict = next(v for v in conformance.check(otmm_run, otmm_scenario) if v.check == otmm_check)
    if not verdict.passed:
        pytest.fail(f"{otmm_scenario.name} {otmm_check}: {verdict.detail}", pytrace=False)
