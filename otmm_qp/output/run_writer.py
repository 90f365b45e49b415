"""Write a run folder while a suite runs: each run's time series as it ends, then the summaries.

:func:`~otmm_qp.runner.run.run_suite` takes a :class:`ResultsWriter` as its ``out`` (any
:class:`~otmm_qp.runner.run.RunSink`); the runner itself knows nothing of files, so the
dependency points one way, ``output → runner``. Every file is written atomically inside the
folder, named through :class:`~otmm_qp.output.results.ResultsDir`, so an interrupted suite is
always reportable.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from otmm_qp.output.results import SUMMARY_CSV, SUMMARY_MD, ResultsDir
from otmm_qp.output.summary import (
    RunOutcome,
    summary_row,
    write_summary_csv,
    write_summary_markdown,
)
from otmm_qp.runner.build import SkippedController
from otmm_qp.runner.episode import RunRecord
from otmm_qp.runner.run import SuiteResult

__all__ = ["ResultsWriter"]


class ResultsWriter:
    """The :class:`~otmm_qp.runner.run.RunSink` that writes an ``otmm-qp run`` folder.

    Args:
        path: The results folder (claimed by the caller, e.g. ``claim_results_dir``).
    """

    def __init__(self, path: Path | str) -> None:
        self.path = Path(path)
        self._results = ResultsDir(self.path)

    def write_run(self, record: RunRecord, controllers: Sequence[str]) -> Path:
        """Write one run's time series to ``<experiment>/<loop mode>/<controller>.csv``.

        Args:
            record: The finished run.
            controllers: Controller names of its experiment, in config order (unique slugs).

        Raises:
            OutputPathError: The path would leave the folder.
        """
        return self._results.write_run(record.result, controllers)

    def write_summaries(self, outcome: SuiteResult) -> None:
        """(Re)write ``summary.csv`` and ``summary.md`` from the records and skips so far."""
        rows = [summary_row(r.identity, r.metrics, r.result.error_message) for r in outcome.records]
        rows += [
            _skipped_row(experiment, mode, skip)
            for experiment, skip in outcome.skipped
            for mode in _loop_modes(outcome, experiment)
        ]
        write_summary_csv(rows, self._results.file(SUMMARY_CSV))
        write_summary_markdown(rows, self._results.file(SUMMARY_MD), outcome.suite.name)


def _loop_modes(outcome: SuiteResult, experiment: str) -> list[str]:
    """The loop modes an experiment of the suite runs (its own, else the suite's)."""
    suite = outcome.suite
    config = next(e for e in suite.experiments if e.name == experiment)
    return list(config.loop_modes or suite.loop_modes)


def _skipped_row(experiment: str, loop_mode: str, skip: SkippedController) -> dict[str, object]:
    """A ``summary.csv`` row for a controller that was skipped: no metrics, the reason."""
    identity = {
        "experiment": experiment,
        "loop_mode": loop_mode,
        "controller": skip.name,
        "filters": skip.filters,
        "backend": skip.backend,
    }
    return summary_row(identity, {"steps": 0, "completed": False}, skip.reason, RunOutcome.SKIPPED)
