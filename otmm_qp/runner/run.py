"""Run a validated suite, handing each run to a sink (e.g. the results folder) as it ends.

The runner writes no files: ``run_suite(suite, out)`` calls ``out.write_run`` after each run
and ``out.write_summaries`` after each change of the outcome, so dependencies point one way
(:class:`otmm_qp.output.run_writer.ResultsWriter` is the sink that writes a run folder).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol, TextIO

from otmm_qp import interrupt
from otmm_qp.config.schema import SuiteConfig
from otmm_qp.metrics.metrics import MetricSettings
from otmm_qp.runner.build import SkippedController
from otmm_qp.runner.episode import RunRecord, run_episode
from otmm_qp.runner.prepare import PreparedExperiment, prepare_experiment


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


class RunSink(Protocol):
    """Where :func:`run_suite` puts each run as it ends (a results folder, for one).

    Attributes:
        path: The folder the sink writes (passed on to ``after_experiment`` hooks).
    """

    path: Path

    def write_run(self, record: RunRecord, controllers: Sequence[str]) -> object:
        """Store one finished run; ``controllers`` are its experiment's names, in order."""
        ...

    def write_summaries(self, outcome: SuiteResult) -> None:
        """Store the summary of every run (and skip) so far."""
        ...


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
    out: RunSink | None,
    source: str = "config",
    progress: TextIO | None = sys.stderr,
    after_experiment: ExperimentHook | None = None,
    prepared: list[PreparedExperiment] | None = None,
) -> SuiteResult:
    """Run all experiments; hand each run and the summaries to ``out`` as they are done.

    Args:
        suite: Validated config.
        out: Where the runs go (``ResultsWriter(folder)`` writes a results folder), or None
            to keep results in memory only.
        source: Config name used in messages.
        progress: Stream for progress lines (None: silent).
        after_experiment: Called with each finished experiment (e.g. to draw figures).
        prepared: Already-built experiments (built here when None).

    Returns:
        All records; ``errors`` lists runs that stopped early (their steps are kept).

    Raises:
        TypeError: ``out`` is not a sink (e.g. a bare path), before any compute.
    """
    if out is not None and not callable(getattr(out, "write_run", None)):
        raise TypeError(
            "run_suite: out must be a RunSink such as otmm_qp.output.run_writer.ResultsWriter"
            f"(folder) or None, got {type(out).__name__}"
        )
    out_dir = out.path if out is not None else None
    experiments = prepared if prepared is not None else prepare_suite(suite, source)
    settings = MetricSettings(**suite.metrics.model_dump())
    outcome = SuiteResult(suite)
    total = sum(len(p.loop_modes) * len(p.controllers) for p in experiments)
    done = 0
    for experiment in experiments:
        records = _run_and_write(experiment, settings, outcome, out)
        done += len(records)
        _progress(progress, f"[{done}/{total} runs] {experiment.config.name} done")
        _record_stops_and_skips(outcome, experiment, records, out, progress)
        if after_experiment is not None:
            after_experiment(experiment, records, out_dir)
    if progress is not None and progress.isatty():
        progress.write("\n")
    return outcome


def _run_and_write(
    experiment: PreparedExperiment,
    settings: MetricSettings,
    outcome: SuiteResult,
    out: RunSink | None,
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
        if out is not None:
            tic = time.perf_counter()
            out.write_run(record, names)
            out.write_summaries(outcome)
            writing += time.perf_counter() - tic

    tic = time.perf_counter()
    records = run_experiment(experiment, settings, finished)
    outcome.compute_seconds += time.perf_counter() - tic - writing
    return records


def _record_stops_and_skips(
    outcome: SuiteResult,
    experiment: PreparedExperiment,
    records: list[RunRecord],
    out: RunSink | None,
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
    if out is not None and experiment.skipped:
        out.write_summaries(outcome)
