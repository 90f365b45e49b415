"""Build experiments from configs and run them."""

from otmm_qp.runner.build import PreparedExperiment, build_controller, prepare_experiment
from otmm_qp.runner.run import RunRecord, SuiteResult, prepare_suite, run_experiment, run_suite

__all__ = [
    "PreparedExperiment",
    "RunRecord",
    "SuiteResult",
    "build_controller",
    "prepare_experiment",
    "prepare_suite",
    "run_experiment",
    "run_suite",
]
