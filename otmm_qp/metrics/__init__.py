"""Run metrics."""

from otmm_qp.metrics.metrics import METRIC_NAMES, Metrics, MetricSettings, compute_metrics

__all__ = ["METRIC_NAMES", "MetricSettings", "Metrics", "compute_metrics"]
