"""Task filters: modify the commanded task velocity before the backend inverts it."""

from otmm_qp.filters.identity import IdentityFilter
from otmm_qp.filters.otmm import OtmmFilter
from otmm_qp.filters.servo_scaling import ServoScalingFilter
from otmm_qp.filters.task_filter import FilterOutput, FilterReport, TaskFilter

__all__ = [
    "FilterOutput",
    "FilterReport",
    "IdentityFilter",
    "OtmmFilter",
    "ServoScalingFilter",
    "TaskFilter",
]
