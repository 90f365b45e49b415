"""Run metrics: their definitions (``metrics.py``) and the one table of labels (``table.py``)."""

from otmm_qp.metrics.metrics import METRIC_NAMES, Metrics, MetricSettings, compute_metrics
from otmm_qp.metrics.table import METRICS, Metric, columns, metric

__all__ = [
    "METRICS",
    "METRIC_NAMES",
    "Metric",
    "MetricSettings",
    "Metrics",
    "columns",
    "compute_metrics",
    "metric",
]
