"""otmm-qp: velocity-level IK controllers compared near kinematic singularities.

The pipeline of one control step::

    state = KinematicState.compute(robot, q)      # J and its SVD, once
    out = controller.step(state, xdot_c, qdot)    # filters (e.g. OTMM) then a backend

Submodules load on first use, so ``import otmm_qp`` (and the pytest plugin, which every
pytest session in an environment with otmm-qp loads) stays cheap.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from otmm_qp.exceptions import OtmmError

if TYPE_CHECKING:
    from otmm_qp.controller import Controller, ControllerOutput
    from otmm_qp.state import KinematicState

__all__ = ["Controller", "ControllerOutput", "KinematicState", "OtmmError"]

_LAZY = {
    "Controller": "otmm_qp.controller",
    "ControllerOutput": "otmm_qp.controller",
    "KinematicState": "otmm_qp.state",
}


def _version() -> str:
    """The version, declared once, in pyproject.toml.

    Read on first use: importing ``importlib.metadata`` took ~80 ms of the CLI's start, before
    it handles Ctrl-C.
    """
    from importlib import metadata

    try:
        return metadata.version("otmm-qp")
    except metadata.PackageNotFoundError:  # a source tree that was never installed
        return "0+unknown"


def __getattr__(name: str) -> Any:
    if name == "__version__":
        return _version()
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'otmm_qp' has no attribute {name!r}")
