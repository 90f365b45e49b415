"""``otmm-qp init study --urdf PATH --frame NAME``: a commented study file for your own arm.

The arm is loaded first, exactly as the study will load it (``PinocchioArm`` with the given
``package_dirs``, ``frame`` and ``locked_joints``), so a missing URDF, a mesh outside its
package, an unknown frame or joint is one line and exit 2 before anything is written. The file
lists the joint limits read from the URDF (position [rad or m], speed [rad/s or m/s]) in a
comment, draws batches of ``--tasks`` tasks over the six task generators in the proportions of
the shipped arms study until the arm is decided or ``--budget`` tasks are spent
(a ``decide`` block, :mod:`otmm_qp.studies.decide`), compares a handful of the field's
controllers, judges success by the arm's own speed limits, and is checked against the study
schema before it is written (atomically; an existing file is kept unless ``--force``).
"""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import yaml

from otmm_qp.exceptions import ConfigError
from otmm_qp.paths import atomic_write_text
from otmm_qp.robots.pinocchio_arm import PinocchioArm

NAME = "init"
HELP = "write a commented study file for your own URDF arm"

#: Share of the tasks per generator (the shipped arms study's 400/200/150/150/100, plus held
#: targets), in the order written.
SHARES = (
    ("near_singular", 0.35, "lines and arcs past singular poses", "distance: [0.0, 0.08]"),
    ("joint_path", 0.2, "joint paths through singular configurations", "offset: [0.0, 0.15]"),
    ("beyond_reach", 0.15, "out-and-back motions past the reach", ""),
    ("boundary", 0.1, "arcs along the workspace boundary", ""),
    ("random_reachable", 0.1, "random reachable targets", ""),
    ("held_target", 0.1, "step targets held still", "targets: 2, hold: 1.0"),
)
#: Largest ``--tasks`` (a study's default ``limits.max_tasks``).
MAX_TASKS = 100_000
#: Suggested output folders tried before giving up on a free one.
MAX_FOLDERS = 100

CONTROLLERS = """\
controllers:                      # the field's strategies; add your own (otmm-qp list --params)
  - name: dls
    backend: {type: dls, damping: 0.05}
  - name: qp                      # keeps the URDF's position and speed limits
    backend: {type: qp, solver: daqp, regularization: 1.0e-3}
  - name: OTMM-linear+qp
    filters: [{type: otmm, sigma_s: 0.05, p: linear, corank: all}]
    backend: {type: qp, solver: daqp, regularization: 1.0e-3}
  - name: OTMM-directional+pinv
    filters: [{type: otmm_directional}]
    backend: {type: pinv}
  - name: sns
    backend: {type: sns}
  - name: dls_error
    backend: {type: dls_error, error_weight: 10.0, error_horizon: 0.1, lambda_sq_floor: 1.0e-4}
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``study --urdf PATH --frame NAME [--task] [--package-dir D ...] [--locked-joints J ...]``."""
    parser.add_argument("what", choices=["study"], help="what to write (a study file)")
    parser.add_argument("--urdf", required=True, help="the arm's URDF file")
    parser.add_argument("--frame", required=True, help="end-effector frame (a link of the URDF)")
    parser.add_argument("--task", choices=["pose", "position"], default="pose")
    parser.add_argument(
        "--package-dir",
        dest="package_dirs",
        action="append",
        default=[],
        metavar="DIR",
        help="folder holding the URDF's package:// packages (repeatable)",
    )
    parser.add_argument(
        "--locked-joints", nargs="+", default=[], metavar="JOINT", help="joints to lock (grippers)"
    )
    parser.add_argument(
        "--tasks", type=int, default=60, help="tasks per batch, split over the generators (60)"
    )
    parser.add_argument(
        "--budget",
        type=int,
        default=600,
        help="most tasks the study may run before it must decide (default 600; 0: one batch)",
    )
    parser.add_argument("-o", "--out", default=None, help="file (default: <urdf name>-study.yaml)")
    parser.add_argument("--force", action="store_true", help="replace an existing file")


def _number(value: float) -> str:
    """A limit as YAML: ``.inf`` / ``-.inf`` or 4 significant digits."""
    if math.isinf(value):
        return ".inf" if value > 0 else "-.inf"
    return f"{value:.4g}"


def zero_speed_joints(urdf: str) -> list[str]:
    """The joints whose URDF ``<limit>`` says ``velocity="0"`` (read as no speed limit).

    Fixed joints are listed too; the caller keeps the arm's movable ones.
    """
    try:
        root = ET.parse(urdf).getroot()  # noqa: S314 - the file Pinocchio has just loaded
    except (ET.ParseError, OSError):
        return []
    zero = []
    for joint in root.iter("joint"):
        limit = joint.find("limit")
        velocity = None if limit is None else limit.get("velocity")
        try:
            if velocity is not None and float(velocity) == 0.0:
                zero.append(str(joint.get("name")))
        except ValueError:
            continue
    return zero


def limit_lines(arm: PinocchioArm, zero_speed: Sequence[str] = ()) -> list[str]:
    """One comment line per joint: name, position range, speed limit (as the study reads them).

    ``zero_speed``: joints whose URDF says ``velocity="0"``, which means no speed limit.
    """
    lower, upper = arm.position_limits
    speeds = np.asarray(arm.velocity_limits, dtype=float)
    names = [str(n) for n in arm.model.names[1:]]
    lines = []
    for j, name in enumerate(names):
        kind = "continuous" if math.isinf(lower[j]) and math.isinf(upper[j]) else "range"
        if name in zero_speed:
            speed = 'none: velocity="0" in the URDF means no limit (set velocity_limits)'
        elif math.isinf(speeds[j]):
            speed = "no limit in the URDF"
        else:
            speed = f"{speeds[j]:.4g}"
        lines.append(
            f"#   {name}: [{_number(lower[j])}, {_number(upper[j])}] ({kind}), speed {speed}"
        )
    return lines


def generator_counts(tasks: int) -> list[int]:
    """``tasks`` (≥ one per generator) split over :data:`SHARES`, summing to ``tasks``.

    One task each, then the rest in proportion to the shares (largest remainders).
    """
    rest = tasks - len(SHARES)
    raw = [share * rest for _, share, _, _ in SHARES]
    counts = [1 + math.floor(r) for r in raw]
    order = sorted(range(len(raw)), key=lambda i: (raw[i] - math.floor(raw[i]), -i), reverse=True)
    for i in order[: tasks - sum(counts)]:
        counts[i] += 1
    return counts


def study_text(
    arm: PinocchioArm,
    args: argparse.Namespace,
    name: str,
    zero_speed: Sequence[str] = (),
    folder: Path | None = None,
) -> str:
    """The commented study file for ``arm`` (paths as given: a relative one stays relative).

    ``folder``: the output folder its run line suggests (default :func:`results_folder`).
    """
    robot: dict[str, object] = {"type": "pinocchio", "urdf": str(args.urdf)}
    if args.package_dirs:
        robot["package_dirs"] = [str(d) for d in args.package_dirs]
    robot["frame"] = args.frame
    robot["task"] = args.task
    if args.locked_joints:
        robot["locked_joints"] = list(args.locked_joints)
    flow = yaml.safe_dump(robot, default_flow_style=True, width=10_000, sort_keys=False).strip()
    weight = "\n    task_weight: [1.0, 1.0, 1.0, 0.2, 0.2, 0.2]  # angular rows [m/rad]" * (
        args.task == "pose"
    )
    orientation = "\n  max_orientation_error: 0.1   # [rad]" * (args.task == "pose")
    counts = generator_counts(args.tasks)
    generators = "\n".join(
        f"  - {{type: {kind}, count: {count}, {extra + ', ' if extra else ''}"
        f"duration: [1.5, 2.5]}}  # {what}"
        if kind != "held_target"
        else f"  - {{type: {kind}, count: {count}, {extra}}}  # {what}"
        for (kind, _, what, extra), count in zip(SHARES, counts, strict=True)
    )
    limits = "\n".join(limit_lines(arm, zero_speed))
    decide = (
        f"decide: {{budget_tasks: {args.budget}, batch: {sum(counts)}}}  # batches until one row "
        "beats\n#   every other on success over the task mix (anytime-valid), or the budget is "
        "spent;\n#   raise budget_tasks and rerun to grow the study (stored episodes are kept)"
        if args.budget
        else "# decide: {budget_tasks: 600, batch: 60}  # instead of one batch: run until decided"
    )
    return f"""\
# A study of {name} written by `otmm-qp init study` ({arm.nv} joints, frame {arm.frame_name},
# {args.task} task). Run it, then read the decision per kind of task:
#   otmm-qp study THIS_FILE --out {folder or results_folder(name)}
# Joint limits read from the URDF (position [rad or m], speed [rad/s or m/s]); success below
# judges every joint against its own speed limit, and the qp rows keep both:
{limits}
name: {name}
description: "{name} ({args.task} task at {arm.frame_name}): the task generators of the
  shipped arms study and the field's strategies, judged by the arm's own limits."
seed: 2026
dt: 0.02                  # [s]
loop_modes: [clik]
clik_gain: 10.0           # [1/s]
duration: {{extra: 0.5}}    # [s] held at the end of each motion
metrics: {{sigma_s: 0.05, window: 1.0, blow_up_speed: 50.0}}
success:
  max_position_error: 0.02     # [m]{orientation}
  joint_speed_factor: 1.0      # every joint within its own URDF speed limit
  graceful: {{error_factor: 1.5, max_jump_factor: 0.5, return_to_path: true}}
  no_limit_violation: true
  no_blow_up: true
robots:
  - name: {name}
    robot: {flow}{weight}
generators:                       # {sum(counts)} tasks per batch, in these proportions
{generators}
{decide}
{CONTROLLERS}"""


def run(args: argparse.Namespace) -> int:
    """Load the arm, write its study file, print where and how to run it.

    Raises:
        OtmmError: Bad input (URDF, meshes, frame, joints, ``--tasks``, ``--out``), one line.
    """
    if not len(SHARES) <= args.tasks <= MAX_TASKS:
        raise ConfigError(
            "--tasks",
            f"must be an integer in [{len(SHARES)}, {MAX_TASKS}] (one task per generator at "
            f"least), got {args.tasks}",
        )
    if not os.path.isfile(args.urdf):
        raise ConfigError("--urdf", f"file not found: {args.urdf}")
    if args.budget and not args.tasks <= args.budget <= MAX_TASKS:
        raise ConfigError(
            "--budget",
            f"must be 0 (one batch) or an integer in [--tasks = {args.tasks}, {MAX_TASKS}], "
            f"got {args.budget}",
        )
    for folder in args.package_dirs:
        if not os.path.isdir(folder):
            raise ConfigError("--package-dir", f"not a folder: {folder}")
    from otmm_qp.runner.build import captured_stderr

    with captured_stderr():  # urdfdom's parser lines are dropped when loading fails
        arm = PinocchioArm(
            urdf=args.urdf,
            package_dirs=args.package_dirs or None,
            frame=args.frame,
            task=args.task,
            locked_joints=args.locked_joints or None,
        )
    name = re.sub(r"[^A-Za-z0-9_.+-]+", "_", arm.name).strip("_") or "arm"  # a study name
    if args.task != "pose":  # another study of the same arm: another name, file and folder
        name = f"{name}-{args.task}"
    out = Path(args.out) if args.out else Path(f"{name}-study.yaml")
    if out.exists() and not args.force:
        raise ConfigError("--out", f"{out} exists; give --force to replace it")
    if not out.parent.is_dir():
        raise ConfigError("--out", f"no folder {out.parent}")
    movable = {str(n) for n in arm.model.names[1:]}
    zero_speed = [j for j in zero_speed_joints(arm.urdf_path or args.urdf) if j in movable]
    from otmm_qp.studies.spec import parse_study

    study = parse_study(yaml.safe_load(study_text(arm, args, name, zero_speed)), str(out))
    folder = free_folder(study.model_dump(mode="json"))
    text = study_text(arm, args, name, zero_speed, folder)
    atomic_write_text(out, text)
    print(f"{out}: a study of {name} ({arm.nv} joints, {args.task} task at {args.frame})")
    print(f"  run: otmm-qp study {out} --out {folder}")
    if zero_speed:
        print(
            f'otmm-qp: warning: {", ".join(zero_speed)}: velocity="0" in the URDF means no speed '
            "limit (set velocity_limits in the robot block for one)",
            file=sys.stderr,
        )
    return 0


def results_folder(name: str, number: int = 1) -> Path:
    """The output folder suggested for study ``name``: ``results/<name>-study[-N]``."""
    return Path("results") / (f"{name}-study" if number == 1 else f"{name}-study-{number}")


def free_folder(config: dict[str, object]) -> Path:
    """The first suggested folder no other study uses (:func:`results_folder`).

    A folder is free when it does not exist, holds no ``study.json`` and nothing else, or
    holds this same study (:func:`otmm_qp.studies.storage.other_study`).
    """
    from otmm_qp.studies.storage import StudyDirectoryError, other_study, read_marker

    name = str(config["name"])
    for number in range(1, MAX_FOLDERS + 1):
        folder = results_folder(name, number)
        if not folder.exists():
            return folder
        if not folder.is_dir():
            continue
        try:
            marker = read_marker(folder)
            if marker is None and not any(folder.iterdir()):
                return folder
        except (StudyDirectoryError, OSError):
            continue
        if marker is not None and other_study(marker, config) is None:
            return folder
    return results_folder(name, MAX_FOLDERS + 1)
