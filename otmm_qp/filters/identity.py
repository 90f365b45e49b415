"""The identity filter: passes the command through."""

from __future__ import annotations

from typing import ClassVar

from otmm_qp.filters.task_filter import FilterOutput, FilterReport, TaskFilter
from otmm_qp.robots.robot import FloatArray
from otmm_qp.state import KinematicState
from otmm_qp.validation import Constraints


class IdentityFilter(TaskFilter):
    """``ẋ_m = ẋ``."""

    name = "identity"
    parameter_constraints: ClassVar[Constraints] = {}

    def apply(self, state: KinematicState, xdot: FloatArray) -> FilterOutput:
        """Return ``xdot`` unchanged."""
        return FilterOutput(xdot, FilterReport(False, state.sigma_min, 0.0, 0.0))
