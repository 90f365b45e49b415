"""Run metrics: their definitions (``metrics.py``) and the one table of labels (``table.py``)."""

from otmm_qp.metrics.metrics import METRIC_NAMES, Metrics, MetricSettings, compute_metrics
from otmm_qp.metrics.table import (
    METRICS,
    STUDY_MEDIANS,
    STUDY_METRICS,
    STUDY_OBJECTIVES,
    STUDY_PAIRED,
    Metric,
    columns,
    metric,
)

__all__ = [
    "METRICS",
    "METRIC_NAMES",
    "STUDY_MEDIANS",
    "STUDY_METRICS",
    "STUDY_OBJECTIVES",
    "STUDY_PAIRED",
    "Metric",
    "MetricSettings",
    "Metrics",
    "columns",
    "compute_metrics",
    "metric",
]
