"""Write the replays of a results folder, and list those already written.

``RESULTS_DIR/replays/<experiment>-<loop_mode>.html`` (URDF arms) or ``.gif`` (planar arms),
each with a ``.json`` sidecar (title, kind, frames) that :func:`find_replays` reads.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, TextIO

from otmm_qp.exceptions import ConfigError, OtmmError
from otmm_qp.output.replays import REPLAY_FOLDER
from otmm_qp.paths import atomic_write_bytes, ensure_inside, safe_name
from otmm_qp.replay.stored_runs import StoredRun, discover_runs, group_scenarios, select_runs
from otmm_qp.robots.robot import Robot


def _unique_stems(keys: Sequence[tuple[str, ...]]) -> dict[tuple[str, ...], str]:
    """Distinct safe file stems for distinct scenario keys (``-2``, ``-3`` on collisions)."""
    stems: dict[tuple[str, ...], str] = {}
    used: set[str] = set()
    for key in keys:
        stem = "-".join(safe_name(part) for part in key)
        candidate, n = stem, 1
        while candidate.lower() in used:
            n += 1
            candidate = f"{stem}-{n}"
        used.add(candidate.lower())
        stems[key] = candidate
    return stems


def _size(n: int) -> str:
    return f"{n / 1e6:.1f} MB" if n >= 1e6 else f"{n / 1e3:.0f} kB"


def write_replays(
    results_dir: Path,
    experiment: str | None = None,
    controller: str | None = None,
    *,
    max_frames: int | None = None,
    max_bytes: int | None = None,
    log: TextIO | None = None,
    quiet: bool = False,
) -> list[Path]:
    """Write one replay per scenario (experiment × loop mode) from the stored time series.

    Args:
        results_dir: A folder written by ``otmm-qp run``.
        experiment: Only this experiment (display or folder name).
        controller: Only this controller.
        max_frames: Frame cap of planar GIFs (default 80).
        max_bytes: Size cap [bytes]: the GIF size, or the HTML's per-frame data.
        log: Stream for one line per replay (default: the current ``sys.stdout``).
        quiet: No lines (warnings still go to ``sys.stderr``).

    Returns:
        The files written.

    Raises:
        ConfigError: No time series, an unknown experiment/controller (listing those
            available), or a robot that cannot be identified; scenarios that could be
            written are written first.
    """
    from otmm_qp.output.folders import claim_folder

    root = Path(results_dir)
    check_run_folder(root)
    runs = select_runs(discover_runs(root), experiment, controller)
    scenarios = group_scenarios(runs)

    def emit(text: str) -> None:
        if not quiet:
            print(text, file=log if log is not None else sys.stdout)

    with claim_folder(ensure_inside(root, root / REPLAY_FOLDER), "replay"):
        written, errors = _write_scenarios(root, scenarios, controller, max_frames, max_bytes, emit)
    if errors:
        raise ConfigError("", f"{len(errors)} of {len(scenarios)} replays not written: {errors[0]}")
    return written


def check_run_folder(root: Path) -> None:
    """Replays read run folders only (a study stores no per-step CSVs).

    Raises:
        ConfigError: ``root`` is not a folder, or is a folder of another kind.
    """
    from otmm_qp.output.folders import folder_kind

    if not root.is_dir():
        raise ConfigError("RESULTS_DIR", f"{root} is not a folder")
    kind = folder_kind(root)
    if kind not in (None, "run"):
        raise ConfigError(
            "RESULTS_DIR", f"{root} is a {kind} folder; otmm-qp replay reads run folders"
        )


def _check_one_arm(group: Sequence[StoredRun]) -> None:
    """One replay shows one arm: every run of a scenario has its joints and dimension.

    Raises:
        ConfigError: The scenario mixes planar (2-D) and spatial (3-D) runs, or joint sets.
    """
    first = group[0]
    for run in group[1:]:
        if run.dimension != first.dimension or run.joint_names != first.joint_names:
            raise ConfigError(
                f"{first.experiment}/{first.loop_mode}",
                f"mixes runs of different arms ({first.path.name}: {first.dimension}-D, "
                f"{len(first.joint_names)} joints; {run.path.name}: {run.dimension}-D, "
                f"{len(run.joint_names)} joints); one replay shows one arm: "
                "choose one with --controller",
            )


def _write_scenarios(
    root: Path,
    scenarios: dict[tuple[str, str], list[StoredRun]],
    controller: str | None,
    max_frames: int | None,
    max_bytes: int | None,
    emit: Callable[[str], None],
) -> tuple[list[Path], list[str]]:
    """Write every scenario's replay into ``root/replays``: the files written, the errors."""
    suffix = (controller,) if controller is not None else ()
    stems = _unique_stems([key + suffix for key in scenarios])
    folder = ensure_inside(root, root / REPLAY_FOLDER)
    written: list[Path] = []
    errors: list[str] = []
    robots: dict[str, Robot] = {}
    for key, group in scenarios.items():
        title = f"{key[0]} — {key[1]}" + (f" — {controller}" if controller else "")
        stem = stems[key + suffix]
        try:
            _check_one_arm(group)
            robot = robots.get(group[0].experiment) or _robot(group)
            robots[group[0].experiment] = robot
            path, note = _write_scenario(
                root, folder, stem, title, robot, group, max_frames, max_bytes
            )
        except OtmmError as error:
            errors.append(str(error))
            continue
        written.append(path)
        emit(f"replay: {path} ({_size(path.stat().st_size)}, {len(group)} controllers, {note})")
    return written, errors


def _write_scenario(
    root: Path,
    folder: Path,
    stem: str,
    title: str,
    robot: Robot,
    group: Sequence[StoredRun],
    max_frames: int | None,
    max_bytes: int | None,
) -> tuple[Path, str]:
    """Write one scenario's GIF (planar arm) or HTML page: its path and a note on its frames."""
    from otmm_qp.replay.arm_page import DEFAULT_MAX_FRAME_BYTES, write_arm_page
    from otmm_qp.replay.planar_animation import (
        DEFAULT_MAX_BYTES,
        DEFAULT_MAX_FRAMES,
        write_planar_animation,
    )

    if group[0].dimension == 2:
        result = write_planar_animation(
            ensure_inside(root, folder / f"{stem}.gif"),
            title,
            robot,
            group,
            max_frames=max_frames or DEFAULT_MAX_FRAMES,
            max_bytes=max_bytes or DEFAULT_MAX_BYTES,
        )
        return result.path, result.plan.describe()
    page = write_arm_page(
        ensure_inside(root, folder / f"{stem}.html"),
        title,
        robot,
        group,
        max_frame_bytes=max_bytes or DEFAULT_MAX_FRAME_BYTES,
    )
    for message in page.warnings:
        print(f"otmm-qp: {message}", file=sys.stderr)
    _write_sidecar(page.path, title, "urdf-html", page.plan.frames, [r.controller for r in group])
    return page.path, page.plan.describe()


def _robot(group: Sequence[StoredRun]) -> Robot:
    from otmm_qp.replay.robot_model import load_robot

    return load_robot(group)


def _write_sidecar(path: Path, title: str, kind: str, frames: int, controllers: list[str]) -> None:
    text = json.dumps(
        {
            "title": title,
            "kind": kind,
            "file": path.name,
            "frames": frames,
            "controllers": controllers,
        },
        indent=1,
    )
    path.with_suffix(".json").parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path.with_suffix(".json"), (text + "\n").encode("utf-8"))


def replay_after_run(results_dir: Path, prepared: Sequence[Any] = ()) -> OtmmError | None:
    """``run --replay`` / ``report --replay``: record the robots, write every replay.

    Args:
        results_dir: The results folder just written.
        prepared: The run's ``PreparedExperiment`` records (their config's robot block is
            written to ``robot.json``); empty for ``report --replay``.

    Returns:
        The error, if a replay could not be written (the caller still writes its report
        and then reports the error), else None.
    """
    from otmm_qp.replay.robot_model import record_robots

    try:
        if prepared:
            robots = {p.config.name: (p.config.robot.type, p.config.robot.params) for p in prepared}
            record_robots(Path(results_dir), robots)
        write_replays(Path(results_dir))
    except OtmmError as error:
        return error
    return None
