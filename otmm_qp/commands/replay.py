"""``otmm-qp replay RESULTS_DIR [--experiment E] [--controller C]``: watch stored runs."""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "replay"
HELP = "write offline replays (3-D HTML for URDF arms, GIF for planar arms) of stored runs"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``otmm-qp replay``."""
    parser.add_argument("results", type=Path, help="results folder written by 'otmm-qp run'")
    parser.add_argument("--experiment", help="only this experiment (default: all)")
    parser.add_argument("--controller", help="only this controller (default: all, switchable)")
    parser.add_argument(
        "--max-frames", type=int, default=None, help="frame cap of planar GIFs (default 80)"
    )
    parser.add_argument(
        "--max-bytes",
        type=int,
        default=None,
        help="size cap [bytes] of a GIF (default 2.5 MB) or of an HTML's frame data (3 MB)",
    )


def run(args: argparse.Namespace) -> int:
    """Write the replays; bad input raises OtmmError (exit 2 in the CLI)."""
    from otmm_qp.exceptions import ConfigError
    from otmm_qp.replay import write_replays

    for option in ("max_frames", "max_bytes"):
        value = getattr(args, option, None)
        if value is not None and value < 2:
            raise ConfigError(f"--{option.replace('_', '-')}", f"must be >= 2, got {value}")
    from otmm_qp.output.folders import lock_folder
    from otmm_qp.replay.write import check_run_folder

    check_run_folder(args.results)  # before the lock, which would create the folder
    with lock_folder(args.results):  # no run writes it meanwhile
        write_replays(
            args.results,
            args.experiment,
            args.controller,
            max_frames=args.max_frames,
            max_bytes=args.max_bytes,
        )
    return 0
