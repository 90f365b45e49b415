"""``otmm-qp run [CONFIG]``: run a YAML experiment file (the embedded paper by default).

Everything the run needs is checked before any compute: the config, every experiment and
controller, the step count, and the results folder (a writable directory, not already holding
results unless ``--force``, locked against a concurrent run).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from otmm_qp.config.load import DEFAULT_CONFIG, embedded_config_path, load_config
from otmm_qp.exceptions import OtmmError
from otmm_qp.paths import safe_name

NAME = "run"
HELP = "run a YAML experiment file"
EXIT_BAD_INPUT = 2


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Config file, results folder, figures, --force, --quiet."""
    parser.add_argument(
        "config", nargs="?", help=f"YAML file (default: the embedded {DEFAULT_CONFIG})"
    )
    parser.add_argument("--out", help="results folder (default: results/<config name>)")
    parser.add_argument(
        "--figures",
        choices=("all", "comparison", "none"),
        default="all",
        help="PNG figures: one per run plus one comparison per experiment and loop mode "
        "(all, the default), only the comparisons, or none",
    )
    parser.add_argument("--no-figures", action="store_true", help="same as --figures none")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")
    parser.add_argument(
        "--max-steps",
        type=int,
        help="cap on control steps per run (default: the config's max_steps, 1000000)",
    )
    parser.add_argument(
        "--replay", action="store_true", help="also write replays (see 'otmm-qp replay')"
    )
    parser.add_argument(
        "--force",
        action="store_true",
        help="replace the results of an earlier run in --out (refused without it)",
    )


def run(args: argparse.Namespace) -> int:
    """Run a config (the embedded paper reproduction by default)."""
    from otmm_qp.output.results_dir import check_out_argument, claim_results_dir
    from otmm_qp.output.run_writer import ResultsWriter
    from otmm_qp.runner.run import prepare_suite, run_suite

    figures = "none" if args.no_figures else args.figures
    out = check_out_argument(args.out) if args.out is not None else None
    if args.max_steps is not None and args.max_steps <= 0:
        raise OtmmError(f"--max-steps: must be > 0, got {args.max_steps}")
    path = Path(args.config) if args.config else embedded_config_path()
    suite = load_config(path)
    # every bad input fails here, before any compute
    prepared = prepare_suite(suite, path.name, max_steps=args.max_steps)
    out_dir = out if out is not None else Path("results") / safe_name(suite.name)
    with claim_results_dir(out_dir, force=args.force) as out_dir:
        hook = None
        progress = None if args.quiet else sys.stderr
        if figures != "none":
            from otmm_qp.output.figures import figure_hook

            hook = figure_hook(suite.metrics.sigma_s, per_run=figures == "all", progress=progress)
        outcome = run_suite(
            suite,
            ResultsWriter(out_dir),
            path.name,
            progress=progress,
            after_experiment=hook,
            prepared=prepared,
        )
        if suite.claims == "paper":
            from otmm_qp.output.claims import judge_paper_claims, write_claims

            write_claims(judge_paper_claims(outcome), out_dir / "claims.md")
        replay_error = None
        if args.replay:
            from otmm_qp.replay.write import replay_after_run

            replay_error = replay_after_run(out_dir, prepared)
        from otmm_qp.output.report import write_report

        report_html, _ = write_report(out_dir)
    print(
        f"{len(outcome.records)} runs in {outcome.compute_seconds:.2f} s of compute -> {out_dir}/"
    )
    print(f"  summary: {out_dir / 'summary.md'}")
    if suite.claims == "paper":
        print(f"  claims:  {out_dir / 'claims.md'}")
    print(f"  report:  {report_html}")
    if replay_error is not None:
        raise replay_error
    for message in outcome.errors:
        print(f"otmm-qp: error: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT if outcome.errors else 0
