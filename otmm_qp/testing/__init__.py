"""Conformance testing of controllers: the scenario suite and its pytest plugin.

Run it against any registered backend::

    pytest --otmm-controller my_backend [--otmm-params '{"gain": 2}']

(the plugin is registered through the ``pytest11`` entry point; without it, add
``-p otmm_qp.testing.pytest_plugin``). See :mod:`otmm_qp.testing.conformance` for the
scenarios and thresholds.
"""

from otmm_qp.testing.conformance import (
    CHECKS,
    ControllerSpec,
    Scenario,
    Verdict,
    check,
    conformance_report,
    parse_controller,
    run_scenario,
    scenarios,
)

__all__ = [
    "CHECKS",
    "ControllerSpec",
    "Scenario",
    "Verdict",
    "check",
    "conformance_report",
    "parse_controller",
    "run_scenario",
    "scenarios",
]
