"""Run a validated suite, writing results as each experiment finishes."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

from otmm_qp.config.schema import SuiteConfig
from otmm_qp.metrics.metrics import MetricSettings
from otmm_qp.output.results import SUMMARY_CSV, SUMMARY_MD, ResultsDir
from otmm_qp.output.summary import (
    RunOutcome,
    summary_row,
    write_summary_csv,
    write_summary_markdown,
)
from otmm_qp.runner import interrupt
from otmm_qp.runner.build import SkippedController
from otmm_qp.runner.episode import RunRecord, run_episode
from otmm_qp.runner.prepare import PreparedExperiment, prepare_experiment
from otmm_qp.simulation.run_result import RunResult


@dataclass
class SuiteResult:
    """All runs of a suite, the messages of runs that stopped early, and skipped controllers.

    ``skipped`` holds ``(experiment, controller)`` pairs whose optional peer library is not
    installed; each becomes a ``summary.csv`` row whose ``error_message`` starts with
    ``skipped:`` and gives the install hint.
    """

    suite: SuiteConfig
    records: list[RunRecord] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    compute_seconds: float = 0.0
    skipped: list[tuple[str, SkippedController]] = field(default_factory=list)

    def find(self, experiment: str, loop_mode: str, controller: str) -> RunRecord | None:
        """The record of one run, or None."""
        for record in self.records:
            r = record.result
            if (r.experiment, r.loop_mode, r.controller) == (experiment, loop_mode, controller):
                return record
        return None


ExperimentHook = Callable[[PreparedExperiment, list[RunRecord], Path | None], None]


def prepare_suite(
    suite: SuiteConfig, source: str = "config", max_steps: int | None = None
) -> list[PreparedExperiment]:
    """Build every experiment first, so bad input fails before any compute.

    Args:
        suite: Validated config.
        source: Config name used in messages.
        max_steps: Cap on control steps per run (None: the config's ``max_steps``).
    """
    return [prepare_experiment(suite, i, source, max_steps) for i in range(len(suite.experiments))]


def run_csv_path(out_dir: Path, result: RunResult, controllers: list[str]) -> Path:
    """Where a run's time series goes (:meth:`ResultsDir.run_csv`).

    Raises:
        OutputPathError: The path would leave ``out_dir``.
    """
    return ResultsDir(out_dir).run_csv(
        result.experiment, result.loop_mode, result.controller, controllers
    )


def run_experiment(
    prepared: PreparedExperiment,
    settings: MetricSettings,
    after_run: Callable[[RunRecord], None] | None = None,
) -> list[RunRecord]:
    """Every (loop mode, controller) run of one experiment; ``after_run`` sees each one."""
    records = []
    for episode in prepared.episodes:
        for controller in prepared.controllers:
            stage = prepared.build_stage(controller.name)
            records.append(run_episode(episode, controller, settings, stage))
            if after_run is not None:
                after_run(records[-1])
    return records


def _progress(stream: TextIO | None, text: str) -> None:
    if stream is None:
        return
    if stream.isatty():
        stream.write("\r\033[K" + text)
    else:
        stream.write(text + "\n")
    stream.flush()


def run_suite(
    suite: SuiteConfig,
    out_dir: Path | None,
    source: str = "config",
    progress: TextIO | None = sys.stderr,
    after_experiment: ExperimentHook | None = None,
    prepared: list[PreparedExperiment] | None = None,
) -> SuiteResult:
    """Run all experiments; write time series and summaries after each experiment.

    Args:
        suite: Validated config.
        out_dir: Results folder, or None to keep results in memory only.
        source: Config name used in messages.
        progress: Stream for progress lines (None: silent).
        after_experiment: Called with each finished experiment (e.g. to draw figures).
        prepared: Already-built experiments (built here when None).

    Returns:
        All records; ``errors`` lists runs that stopped early (their steps are kept).
    """
    experiments = prepared if prepared is not None else prepare_suite(suite, source)
    settings = MetricSettings(**suite.metrics.model_dump())
    outcome = SuiteResult(suite)
    total = sum(len(p.loop_modes) * len(p.controllers) for p in experiments)
    done = 0
    for experiment in experiments:
        records = _run_and_write(experiment, settings, outcome, out_dir)
        done += len(records)
        _progress(progress, f"[{done}/{total} runs] {experiment.config.name} done")
        _record_stops_and_skips(outcome, experiment, records, out_dir, progress)
        if after_experiment is not None:
            after_experiment(experiment, records, out_dir)
    if progress is not None and progress.isatty():
        progress.write("\n")
    return outcome


def _run_and_write(
    experiment: PreparedExperiment,
    settings: MetricSettings,
    outcome: SuiteResult,
    out_dir: Path | None,
) -> list[RunRecord]:
    """Run one experiment, writing each run as it ends; add its compute time to ``outcome``."""
    names = [c.name for c in experiment.controllers]
    writing = 0.0  # seconds spent writing, kept out of compute_seconds

    def finished(record: RunRecord) -> None:
        # Each run is on disk (atomically) and in the summary as soon as it ends, so an
        # interrupted suite is always reportable.
        nonlocal writing
        outcome.records.append(record)
        interrupt.check()
        if out_dir is not None:
            tic = time.perf_counter()
            record.result.write_csv(run_csv_path(out_dir, record.result, names))
            write_summaries(outcome, out_dir)
            writing += time.perf_counter() - tic

    tic = time.perf_counter()
    records = run_experiment(experiment, settings, finished)
    outcome.compute_seconds += time.perf_counter() - tic - writing
    return records


def _record_stops_and_skips(
    outcome: SuiteResult,
    experiment: PreparedExperiment,
    records: list[RunRecord],
    out_dir: Path | None,
    progress: TextIO | None,
) -> None:
    """Add the experiment's early stops and skipped controllers to ``outcome`` (and summaries)."""
    for record in records:
        if record.result.error_message:
            r = record.result
            outcome.errors.append(f"{r.experiment}/{r.loop_mode}/{r.controller}: {r.error_message}")
    for skip in experiment.skipped:
        outcome.skipped.append((experiment.config.name, skip))
        _progress(progress, f"{experiment.config.name}/{skip.name}: skipped ({skip.reason})")
    if out_dir is not None and experiment.skipped:
        write_summaries(outcome, out_dir)


def write_summaries(outcome: SuiteResult, out_dir: Path) -> None:
    """(Re)write ``summary.csv`` and ``summary.md`` from the records so far."""
    rows = [summary_row(r.identity, r.metrics, r.result.error_message) for r in outcome.records]
    rows += [
        _skipped_row(experiment, mode, skip)
        for experiment, skip in outcome.skipped
        for mode in _loop_modes(outcome.suite, experiment)
    ]
    results = ResultsDir(out_dir)
    write_summary_csv(rows, results.file(SUMMARY_CSV))
    write_summary_markdown(rows, results.file(SUMMARY_MD), outcome.suite.name)


def _loop_modes(suite: SuiteConfig, experiment: str) -> list[str]:
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
