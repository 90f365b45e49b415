"""Build experiments from configs, prepare their episodes and run them."""

from otmm_qp.runner.build import build_controller
from otmm_qp.runner.episode import RunRecord, run_episode
from otmm_qp.runner.prepare import PreparedExperiment, make_episode, prepare, prepare_experiment
from otmm_qp.runner.run import RunSink, SuiteResult, prepare_suite, run_experiment, run_suite

__all__ = [
    "PreparedExperiment",
    "RunRecord",
    "RunSink",
    "SuiteResult",
    "build_controller",
    "make_episode",
    "prepare",
    "prepare_experiment",
    "prepare_suite",
    "run_episode",
    "run_experiment",
    "run_suite",
]
