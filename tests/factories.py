"""Shared test configurations: the tiny run and study files the CLI and hostile tests start from.

One factory instead of a copy per test file (qpsolvers' ``tests/problems.py``). ``tiny_run()``
returns the YAML text of a one-experiment run on the 2-link planar arm tracking a circle from
its elbow-bent start; the arguments change only what a test is about (its controllers, its
duration, a plant line, extra experiments). The text keeps one key per line, so a test derives
a hostile variant with ``str.replace`` on a key (``"dt: 0.02"``, ``"backend: {type: pinv}"``).
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
import subprocess
import sys
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from otmm_qp.replay.browser import Page, chromium_page, find_chromium
from otmm_qp.trajectories.trajectory import Trajectory

#: The 2-link planar arm [m] (reach 1.8 m; singular where the elbow is straight).
PLANAR = "{type: planar, link_lengths: [1.0, 0.8]}"
#: Its start [rad]: on the circle below, elbow bent.
Q0 = "[0.927, -2.5]"

#: Controller items (the text after ``- `` in a ``controllers:`` list).
OTMM_PINV = "name: OTMM\nfilters: [{type: otmm, sigma_s: 0.05, p: linear}]\nbackend: {type: pinv}"
PINV = "{name: pinv, backend: {type: pinv}}"
DLS = "{name: dls, backend: {type: dls, damping: 0.05}}"
#: The same two, one key per line.
PINV_ITEM = "name: pinv\nbackend: {type: pinv}"
DLS_ITEM = "name: dls\nbackend: {type: dls, damping: 0.05}"


def controller_items(items: Sequence[str], indent: int = 6) -> str:
    """A YAML list of ``items``, each ``- item`` at ``indent`` spaces (a multi-line item's
    further lines two more), one line per key."""
    lines = []
    for item in items:
        first, *rest = item.split("\n")
        lines.append(" " * indent + "- " + first)
        lines.extend(" " * (indent + 2) + line for line in rest)
    return "\n".join(lines) + "\n"


def experiment(
    controllers: Sequence[str] = (OTMM_PINV,),
    *,
    name: str = "A",
    duration: float = 0.4,
    radius: float = 0.6,
    period: float = 10.0,
    extra: str = "",
) -> str:
    """One experiment item: the planar arm from :data:`Q0` tracking a circle of ``radius`` [m]
    centred at (1.2, 0) m in ``period`` [s] for ``duration`` [s]; ``extra`` is inserted (indented
    by the caller) before ``controllers:``."""
    return (
        f"  - name: {name}\n"
        f"    robot: {PLANAR}\n"
        f"    q0: {Q0}\n"
        "    trajectory: {type: circle, centre: [1.2, 0.0], "
        f"radius: {radius}, period: {period}}}\n"
        f"    duration: {duration}\n"
        f"{extra}"
        "    controllers:\n"
        f"{controller_items(controllers)}"
    )


def tiny_run(
    controllers: Sequence[str] = (OTMM_PINV,),
    *,
    name: str = "tiny",
    dt: float = 0.02,
    experiment_name: str = "A",
    duration: float = 0.4,
    radius: float = 0.6,
    period: float = 10.0,
    loop_modes: str = "[clik]",
    header: str = "",
    extra: str = "",
    more: str = "",
) -> str:
    """The YAML text of a run ``name`` at ``dt`` [s]: :func:`experiment` ``experiment_name``,
    then ``more`` (further experiment items); ``header`` holds extra top-level lines."""
    first = experiment(
        controllers,
        name=experiment_name,
        duration=duration,
        radius=radius,
        period=period,
        extra=extra,
    )
    return (
        f"\nname: {name}\ndt: {dt}\nloop_modes: {loop_modes}\n{header}experiments:\n" + first + more
    )


#: The UR5's wrist-crossing start [rad] and pose-line end (position [m], quaternion x, y, z, w).
UR5_WRIST_Q0 = "[0.0, -1.2, 1.5, -1.8, 0.3, 0.0]"
UR5_WRIST_END = "[0.6214, 0.1878, 0.3384]"
UR5_WRIST_QUATERNION = "[-0.5539, 0.5836, 0.43954, 0.39926]"


def ur5_wrist_run(
    name: str,
    controllers: Sequence[str],
    *,
    motion: float,
    duration: float | None = None,
    experiment: str = "wrist",
) -> str:
    """The YAML text of a run of the UR5 (6-D pose task, weights 1 m / 0.2 rad) from
    :data:`UR5_WRIST_Q0` along a pose line through its wrist singularity in ``motion`` [s],
    held until ``duration`` [s] (default: ``motion``), at dt = 0.01 s."""
    return (
        f"name: {name}\n"
        "dt: 0.01\n"
        "loop_modes: [clik]\n"
        "experiments:\n"
        f"  - name: {experiment}\n"
        "    robot: {type: pinocchio, name: ur5, task: pose}\n"
        "    task_weight: [1.0, 1.0, 1.0, 0.2, 0.2, 0.2]\n"
        f"    q0: {UR5_WRIST_Q0}\n"
        "    trajectory:\n"
        "      type: pose_line\n"
        f"      end: {UR5_WRIST_END}\n"
        f"      end_quaternion: {UR5_WRIST_QUATERNION}\n"
        f"      duration: {motion}\n"
        f"    duration: {motion if duration is None else duration}\n"
        "    controllers:\n"
        f"{controller_items(controllers)}"
    )


#: Study rows and robots (dicts, as ``parse_study`` takes them).
PLANAR2 = {"name": "planar2", "robot": {"type": "planar", "link_lengths": [1.0, 0.8]}}
PINV_ROW = {"name": "pinv", "backend": {"type": "pinv"}}
DLS_ROW = {"name": "dls", "backend": {"type": "dls", "damping": 0.05}}
#: Success criteria of the small studies: 2 cm, 10 rad/s.
LOOSE_SUCCESS = {"max_position_error": 0.02, "max_joint_speed": 10.0}


def tiny_study(
    name: str,
    *,
    seed: int,
    chunk_size: int,
    generators: Sequence[Mapping[str, Any]],
    controllers: Sequence[Mapping[str, Any]] = (PINV_ROW, DLS_ROW),
    robots: Sequence[Mapping[str, Any]] = (PLANAR2,),
    **keys: Any,
) -> dict[str, Any]:
    """A study dict at dt = 0.05 s with 0.2 s held after each motion; ``keys`` (time_series,
    reference, success, ...) go between ``chunk_size`` and ``robots``, in the order given."""
    return {
        "name": name,
        "seed": seed,
        "dt": 0.05,
        "duration": {"extra": 0.2},
        "chunk_size": chunk_size,
        **keys,
        "robots": [dict(r) for r in robots],
        "generators": [dict(g) for g in generators],
        "controllers": [dict(c) for c in controllers],
    }


def reference_study(
    name: str,
    *,
    seed: int,
    chunk_size: int,
    generators: Sequence[Mapping[str, Any]],
    controllers: Sequence[Mapping[str, Any]] = (PINV_ROW, DLS_ROW),
    robots: Sequence[Mapping[str, Any]] = (PLANAR2,),
) -> dict[str, Any]:
    """:func:`tiny_study` without time series, judged by :data:`LOOSE_SUCCESS`: the reference's
    study (the oracle on by default)."""
    return tiny_study(
        name,
        seed=seed,
        chunk_size=chunk_size,
        time_series={"tasks": 0},
        success=LOOSE_SUCCESS,
        generators=generators,
        controllers=controllers,
        robots=robots,
    )


@contextlib.contextmanager
def browser_page(width: int, height: int) -> Iterator[Page]:
    """A headless Chromium page of ``width`` × ``height`` [px]; skipped without Chromium, except
    in CI (``CI`` set), where its absence fails."""
    if find_chromium() is None:
        if os.environ.get("CI"):
            pytest.fail(
                "Chromium is required for the browser tests in CI (apt-get install chromium)"
            )
        pytest.skip("Chromium not installed: browser tests skipped (apt-get install chromium)")
    with chromium_page(width, height) as page:
        yield page


#: The repository's root (the folder holding ``benchmarks/`` and ``tools/``).
ROOT = Path(__file__).resolve().parents[1]


def load_script(relative: str) -> ModuleType:
    """The repository script at ``relative`` (``benchmarks/bench_x.py``, ``tools/x.py``) imported
    as a module named by its stem (registered in ``sys.modules``, so its dataclasses pickle)."""
    path = ROOT / relative
    spec = importlib.util.spec_from_file_location(path.stem, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[path.stem] = module
    spec.loader.exec_module(module)
    return module


#: A value for each old keyword of the schema-change table (``migration.changes.CHANGES``).
OLD_KEYWORD_EXAMPLES: dict[str, Any] = {
    "limit_gain": 0.2,
    "acceleration_limit": 30.0,
    "singularity_barrier": {"sigma_safe": 0.02},
    "max_speed": 1.0,
    "posture_weight": 0.1,
    "posture_gain": 2.0,
    "q_nominal": [0.0],
    "damping_floor": 1e-4,
    "max_damping": 0.1,
}


def live_processes(field: int, value: int) -> list[int]:
    """Live (not zombie) process ids whose ``/proc/PID/stat`` field ``field`` after the command
    name equals ``value`` (1: the parent's id, 2: the process group)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[field]) == value and fields[0] != "Z":
                found.append(int(entry.name))
    return found


def run_script(
    relative: str, *args: str, timeout: float | None = None
) -> subprocess.CompletedProcess[str]:
    """The repository script at ``relative`` run by this interpreter with ``args`` (output
    captured as text, the exit status left to the caller)."""
    return subprocess.run(
        [sys.executable, str(ROOT / relative), *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )


class Hold(Trajectory):
    """A fixed target from t = 0: a point ``(d,)`` [m] or a pose ``(4, 4)``, at rest."""

    def __init__(self, target: np.ndarray) -> None:
        self.target = np.asarray(target, dtype=float)

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        return self.target.copy(), np.zeros(6 if self.target.ndim == 2 else self.target.size)


def joint_waypoints(
    robot: Any, rng: np.random.Generator, q0: np.ndarray, spread: float, duration: float
) -> Trajectory:
    """A joint-waypoint task from ``q0``: three knots, each a uniform ``±spread`` [rad] step on.

    The knots are drawn from ``rng`` after ``q0`` (so a caller's seed gives the same task as
    before this helper existed).
    """
    from otmm_qp.trajectories.waypoints import JointWaypointsTrajectory

    knots = q0 + np.cumsum(rng.uniform(-spread, spread, (3, robot.nv)), axis=0)
    x0 = robot.forward(robot.configuration(q0))
    return JointWaypointsTrajectory(x0, robot, np.vstack([q0, knots]).tolist(), duration=duration)
