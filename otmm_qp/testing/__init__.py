"""Conformance testing of controllers: the scenario suite and its pytest plugin.

Run it against any registered backend::

    pytest --otmm-controller my_backend [--otmm-params '{"gain": 2}']

(the plugin is registered through the ``pytest11`` entry point; without it, add
``-p otmm_qp.testing.pytest_plugin``). See :mod:`otmm_qp.testing.conformance` for the
scenarios and thresholds.
"""

from __future__ import annotations

import importlib
from typing import Any

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


def __getattr__(name: str) -> Any:
    # Lazy: the pytest plugin lives in this package and must not import the simulator
    # into every pytest session.
    if name in __all__:
        return getattr(importlib.import_module("otmm_qp.testing.conformance"), name)
    raise AttributeError(f"module 'otmm_qp.testing' has no attribute {name!r}")
