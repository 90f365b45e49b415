"""Command-line interface: ``otmm-qp [run CONFIG] | list | report DIR | bench``.

Bad input of any kind prints one line ``otmm-qp: error: ...`` and exits with status 2;
results already computed are written before the error is reported.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from otmm_qp import registry
from otmm_qp.config.load import DEFAULT_CONFIG, embedded_config_path, load_config
from otmm_qp.exceptions import OtmmError

EXIT_BAD_INPUT = 2


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="otmm-qp",
        description="Compare velocity-level IK controllers near kinematic singularities. "
        "With no command, reproduces the OTMM paper into ./results/paper.",
    )
    commands = parser.add_subparsers(dest="command")
    run = commands.add_parser("run", help="run a YAML experiment file")
    run.add_argument(
        "config", nargs="?", help=f"YAML file (default: the embedded {DEFAULT_CONFIG})"
    )
    run.add_argument("--out", type=Path, help="results folder (default: results/<config name>)")
    run.add_argument(
        "--figures",
        choices=("all", "comparison", "none"),
        default="all",
        help="PNG figures: one per run plus one comparison per experiment and loop mode "
        "(all, the default), only the comparisons, or none",
    )
    run.add_argument("--no-figures", action="store_true", help="same as --figures none")
    run.add_argument("--quiet", action="store_true", help="no progress lines")
    run.add_argument(
        "--replay", action="store_true", help="also write replays (see 'otmm-qp replay')"
    )
    commands.add_parser(
        "list", help="list registered robots, filters, p-functions, backends, trajectories"
    )
    report = commands.add_parser(
        "report", help="write report.html and report.md for a results folder"
    )
    report.add_argument("results", type=Path)
    report.add_argument(
        "--replay", action="store_true", help="also write replays (see 'otmm-qp replay')"
    )
    from otmm_qp.commands import replay as replay_command

    replay_command.add_arguments(commands.add_parser(replay_command.NAME, help=replay_command.HELP))
    bench = commands.add_parser("bench", help="time one control step of each pipeline")
    bench.add_argument("--out", type=Path, default=Path("results/bench"))
    bench.add_argument("--steps", type=int, default=300)
    return parser


def command_run(
    config: str | None,
    out: Path | None,
    figures: bool,
    per_run: bool,
    quiet: bool,
    replay: bool = False,
) -> int:
    """Run a config (the embedded paper reproduction by default)."""
    from otmm_qp.runner.run import prepare_suite, run_suite

    path = Path(config) if config else embedded_config_path()
    suite = load_config(path)
    source = path.name
    prepared = prepare_suite(suite, source)  # every bad input fails here, before any compute
    out_dir = out if out is not None else Path("results") / suite.name
    hook = None
    if figures:
        from otmm_qp.output.figures import figure_hook

        hook = figure_hook(suite.metrics.sigma_s, per_run=per_run)
    progress = None if quiet else sys.stderr
    outcome = run_suite(
        suite, out_dir, source, progress=progress, after_experiment=hook, prepared=prepared
    )
    if suite.claims == "paper":
        from otmm_qp.output.claims import judge_paper_claims, write_claims

        write_claims(judge_paper_claims(outcome), out_dir / "claims.md")
    replay_error: OtmmError | None = None
    if replay:
        from otmm_qp.replay import write_replays
        from otmm_qp.replay.robot_model import record_robots

        record_robots(
            out_dir, {p.config.name: (p.config.robot.type, p.config.robot.params) for p in prepared}
        )
        try:
            write_replays(out_dir)
        except OtmmError as error:  # the runs are stored; still write the report
            replay_error = error
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
    if outcome.errors:
        for message in outcome.errors:
            print(f"otmm-qp: error: {message}", file=sys.stderr)
        return EXIT_BAD_INPUT
    return 0


def command_list() -> int:
    """Print every registered plugin, by group."""
    for group in registry.GROUPS:
        print(f"{group.rsplit('.', 1)[-1]}:")
        for name, spec in registry.specs(group).items():
            print(f"  {name:<24} {spec.value}  [{spec.distribution}]")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``otmm-qp`` console script."""
    args = _parser().parse_args(argv)
    try:
        if args.command in (None, "run"):
            figures = (
                "none" if getattr(args, "no_figures", False) else getattr(args, "figures", "all")
            )
            return command_run(
                getattr(args, "config", None),
                getattr(args, "out", None),
                figures != "none",
                figures == "all",
                getattr(args, "quiet", False),
                getattr(args, "replay", False),
            )
        if args.command == "list":
            return command_list()
        if args.command == "report":
            from otmm_qp.output.report import write_report

            replay_error: OtmmError | None = None
            if args.replay:
                from otmm_qp.replay import write_replays

                try:
                    write_replays(args.results)
                except OtmmError as error:  # still write the report
                    replay_error = error
            html, markdown = write_report(args.results)
            print(f"report: {html}\n        {markdown}")
            if replay_error is not None:
                raise replay_error
            return 0
        if args.command == "replay":
            from otmm_qp.commands import replay as replay_command

            return replay_command.run(args)
        if args.command == "bench":
            from otmm_qp.bench import run_bench

            return run_bench(args.out, args.steps)
    except OtmmError as error:
        print(f"otmm-qp: error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("otmm-qp: interrupted", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
