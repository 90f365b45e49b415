"""``otmm-qp study show DIR --episode ID``: one stored episode's spec and a config re-running it.

Prints the episode's robot, task, controller, loop mode, success and failure causes and its
metrics, and writes ``DIR/drilldown/episode-ID.yaml``: an ``otmm-qp run`` config that
reproduces the stored metrics exactly (``otmm-qp run FILE --out DIR/drilldown/episode-ID``,
then ``otmm-qp replay`` on that folder).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from otmm_qp.exceptions import ConfigError

HELP = "one stored episode's spec, and a run config that re-runs it (DIR --episode ID)"

#: Row columns printed under "metrics".
SHOWN_METRICS = (
    "max_error",
    "final_error",
    "max_orientation_error",
    "max_joint_speed",
    "max_speed_ratio",
    "max_jump",
    "position_violations",
    "blow_up",
    "steps",
)


def _text(value: Any) -> str:
    if isinstance(value, float):
        return "–" if math.isnan(value) else f"{value:.6g}"
    return str(value)


def describe(row: dict[str, Any], causes: tuple[str, ...]) -> list[str]:
    """Lines describing a stored episode row."""
    from otmm_qp.studies.drilldown import episode_id

    params = json.loads(str(row.get("generator_params") or "{}"))
    lines = [
        f"episode {episode_id(str(row['episode_key']))} (key {row['episode_key']})",
        f"  study:      {row.get('study')}",
        f"  task:       {row.get('task_id') or '-'}: robot {row['robot']}, generator "
        f"{row['generator']} {json.dumps(params, sort_keys=True)}, task {row['task_index']}, "
        f"seed {row['task_seed']}",
        f"  controller: {row['controller']} (filters {row.get('filters')}, backend "
        f"{row.get('backend')}, {row.get('controller_params')}), loop mode {row['loop_mode']}",
        f"  status:     {row.get('status')}"
        + (f": {row['error_message']}" if row.get("error_message") else ""),
        f"  success:    {'yes' if not causes else 'no: ' + ', '.join(causes)}",
        "  metrics:    " + ", ".join(f"{m} = {_text(row[m])}" for m in SHOWN_METRICS if m in row),
    ]
    reference = {k: v for k, v in row.items() if k.startswith("reference.")}
    if reference:
        lines.append(
            "  reference:  " + ", ".join(f"{k[10:]} = {_text(v)}" for k, v in reference.items())
        )
    return lines


def show(out: Path, wanted: str) -> int:
    """Print the episode ``wanted`` of the study in ``out`` and write its run config."""
    from otmm_qp.paths import ensure_inside, safe_name
    from otmm_qp.studies.criteria import failure_causes
    from otmm_qp.studies.drilldown import episode_id, find_episode, run_config, write_run_config
    from otmm_qp.studies.rows import load_rows

    config, rows = load_rows(out)
    row = find_episode(rows.rows, wanted, str(out))
    if row.get("controller") == "oracle":
        raise ConfigError(
            "--episode", f"{wanted!r} is the task's offline reference (oracle), not an episode"
        )
    for line in describe(row, failure_causes(row, config.success)):
        print(line)
    if row.get("status") == "error":
        print("  (no run config: the episode never ran)")
        return 0
    identity = episode_id(str(row["episode_key"]))
    path = ensure_inside(out, out / "drilldown" / f"{safe_name(f'episode-{identity}')}.yaml")
    folder = path.parent
    if folder.is_symlink() or (folder.exists() and not folder.is_dir()):
        raise ConfigError(str(folder), "is not a folder; move it away to write the run config")
    record = run_config(config, row)
    try:
        folder.mkdir(exist_ok=True)
        write_run_config(path, record)
    except OSError as error:
        reason = error.strerror or type(error).__name__
        raise ConfigError(str(path), f"cannot write the run config: {reason}") from None
    print(f"  run config: {path}")
    print(f"  re-run:     otmm-qp run {path} --out {path.with_suffix('')}")
    return 0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The study directory and ``--episode``."""
    parser.add_argument("directory", type=Path, help="the study directory holding the episode")
    parser.add_argument(
        "--episode", required=True, help="episode id (the report's 'id' column, or a longer prefix)"
    )


def run(args: argparse.Namespace) -> int:
    """``study show DIR --episode ID``."""
    if not args.episode:
        raise ConfigError("--episode", "give an episode id (the report's 'id' column)")
    return show(Path(args.directory), str(args.episode))
