"""``otmm-qp study run FILE`` (or ``otmm-qp study FILE``): run a study and write its report."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from otmm_qp.exceptions import ConfigError

if TYPE_CHECKING:
    from otmm_qp.studies.execute import StudyOutcome
    from otmm_qp.studies.spec import StudyPlan

HELP = "run a study (many random tasks x controllers) into a Parquet dataset, with a report"

EXIT_INTERRUPTED = 130
EXIT_BAD_INPUT = 2


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``otmm-qp study run``."""
    parser.add_argument("file", type=Path, help="YAML study file")
    parser.add_argument("--out", help="output directory (default: results/<safe study name>)")
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--workers",
        type=int,
        help="worker processes of an embedded Dask LocalCluster (default: cores); "
        "1 runs in this process without Dask",
    )
    where.add_argument("--scheduler", help="address of an existing Dask scheduler, tcp://host:port")
    parser.add_argument(
        "--resume", action="store_true", help="skip episodes already stored (also the default)"
    )
    parser.add_argument(
        "--force", action="store_true", help="replace the dataset of another study in --out"
    )
    parser.add_argument("--no-report", action="store_true", help="do not write the report")
    parser.add_argument(
        "--highlight", help="a controller placed as 'ours' on each group's Pareto front (report)"
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    """Run the study; exit 0, 2 (bad input, or episodes that failed) or 130 (interrupted).

    Every episode is stored, a failed one (a plugin exception, a malformed ``q̇``, an
    infeasible QP under ``raise``) with its ``status`` and ``error_message``; the exit status
    is then 2, as for ``run``, after the report is written.
    """
    from otmm_qp.studies.execute import run_study
    from otmm_qp.studies.spec import load_study, plan_study

    if args.workers is not None and args.workers < 1:
        raise ConfigError("--workers", f"must be >= 1, got {args.workers}")
    from otmm_qp.output.folders import check_out_argument
    from otmm_qp.paths import safe_name

    given = check_out_argument(args.out) if args.out is not None else None
    config = load_study(args.file)
    if config.decide is not None:  # batches until decided: the folder holds the full budget
        from otmm_qp.studies.decide import budget_config

        config = budget_config(config, config.decide)
    plan = plan_study(config, str(args.file))
    out = given if given is not None else Path("results") / safe_name(config.name)
    names = [c.name for c in plan.controllers]
    if args.highlight is not None and args.highlight not in names:
        raise ConfigError(
            "--highlight",
            f"no controller {args.highlight!r:.60} in the study; have: {', '.join(names)}",
        )
    for name, reason in plan.skipped:
        print(f"otmm-qp: skipped controller {name}: {reason}", file=sys.stderr)
    if config.decide is not None:
        from otmm_qp.studies.decide import run_decided_study

        outcome = run_decided_study(
            plan,
            config.decide,
            out,
            str(args.file),
            (args.workers, args.scheduler),
            args.force,
            None if args.quiet else PlainProgress(len(plan.episodes)),
        )
    elif args.quiet:
        outcome = run_study(plan, out, str(args.file), args.workers, args.scheduler, args.force)
    elif not sys.stdout.isatty():  # a file or a pipe: plain lines, not a live bar
        outcome = run_study(
            plan,
            out,
            str(args.file),
            args.workers,
            args.scheduler,
            args.force,
            progress=PlainProgress(len(plan.episodes)),
        )
    else:
        outcome = _run_with_progress(plan, out, args)
    rate = outcome.ran / outcome.seconds if outcome.seconds > 0 else 0.0
    steps = outcome.steps / outcome.seconds if outcome.seconds > 0 else 0.0
    print(
        f"{outcome.ran} episodes run ({outcome.failed} failed), {outcome.skipped_stored} already "
        f"stored, of {outcome.total}; {outcome.seconds:.1f} s, {rate:.1f} episodes/s, "
        f"{steps:.0f} steps/s -> {out}/"
    )
    if not (args.no_report or outcome.interrupted):  # a stop stops; the rerun writes it
        from otmm_qp.studies.report import write_study_report
        from otmm_qp.studies.storage import writing_report

        with writing_report(out):
            html, markdown = write_study_report(out, args.highlight)
        print(f"  report: {html}\n          {markdown}")
    if outcome.interrupted:
        print(
            "otmm-qp: interrupted; every finished episode is stored (rerun to resume)",
            file=sys.stderr,
        )
        return EXIT_INTERRUPTED
    if outcome.failed:
        print(
            f"otmm-qp: error: {outcome.failed} of {outcome.ran} episodes failed or stopped early; "
            "they are stored with status 'error' or 'stopped' and their error_message",
            file=sys.stderr,
        )
        return EXIT_BAD_INPUT
    return 0


class PlainProgress:
    """Progress as plain lines on stdout (when it is not a terminal): every 10 % or minute.

    A :data:`~otmm_qp.studies.execute.ProgressHook`: called with the episodes finished and
    failed in each chunk. ``total`` counts the episodes of the run's plan (a ``decide``
    study's full budget: a decision stops it earlier).
    """

    def __init__(self, total: int, every: float = 60.0) -> None:
        import time

        self.total = max(total, 1)
        self.every = every
        self.done = 0
        self.failed = 0
        self.clock = time.perf_counter
        self.start = self.clock()
        self.shown = (0.0, 0)  # (time, tenths of the total) of the last line

    def __call__(self, done: int, failed: int) -> None:
        """Count a chunk; print a line past each tenth of the total or after ``every`` s."""
        self.done += done
        self.failed += failed
        now = self.clock()
        tenth = 10 * self.done // self.total
        if tenth <= self.shown[1] and now - self.shown[0] < self.every:
            return
        self.shown = (now, tenth)
        elapsed = now - self.start
        print(
            f"{self.done} of {self.total} episodes ({self.failed} failed), {elapsed / 60:.1f} min",
            flush=True,
        )


def _run_with_progress(plan: StudyPlan, out: Path, args: argparse.Namespace) -> StudyOutcome:
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    from otmm_qp.studies.execute import run_study

    columns = (
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[rate]:.1f} ep/s"),
        TextColumn("failed {task.fields[failed]}"),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
    )
    with Progress(*columns, transient=False) as bar:
        stored = 0
        task = bar.add_task(plan.config.name, total=len(plan.episodes), rate=0.0, failed=0)
        failures = 0
        import time

        tic = time.perf_counter()

        def hook(done: int, failed: int) -> None:
            nonlocal failures, stored
            failures += failed
            stored += done
            elapsed = max(time.perf_counter() - tic, 1e-9)
            bar.update(task, advance=done, rate=stored / elapsed, failed=failures)

        outcome = run_study(
            plan, out, str(args.file), args.workers, args.scheduler, args.force, progress=hook
        )
        bar.update(task, completed=outcome.skipped_stored + outcome.ran)
    return outcome
