r"""Which robot a stored run used: a recorded description, or recovered from the time series.

The results of ``otmm-qp run`` hold joint coordinates and end-effector positions but not
the robot block of the config. A replay therefore uses, in order:

1. ``<experiment folder>/robot.json`` (``{"type": ..., "params": {...}}``, the config's
   robot block) when present; :func:`record_robots` writes it (through
   :meth:`~otmm_qp.output.results.ResultsDir.write_robot_record`).
2. For 2-D positions, a planar arm whose link lengths are the least-squares solution of the
   forward kinematics over all stored steps (linear in the lengths):

   .. math:: \begin{bmatrix}\cos\Theta\\ \sin\Theta\end{bmatrix} l =
             \begin{bmatrix}x\\ y\end{bmatrix},\qquad \Theta_{k,i} = \sum_{j\le i} q_{k,j}

   accepted only if it reproduces every stored position within 1 µm.
3. For 3-D positions, the example-robot-data arm with the same joint names whose forward
   kinematics puts one of its frames on the stored positions (within 1 µm).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from otmm_qp.exceptions import ConfigError, OtmmError
from otmm_qp.output.results import ROBOT_JSON, ResultsDir
from otmm_qp.replay.stored_runs import StoredRun
from otmm_qp.robots.robot import FloatArray, Robot

#: Largest position mismatch [m] accepted when recovering a robot from its time series.
MATCH_TOLERANCE = 1e-6


def _sample_rows(run: StoredRun, count: int = 8) -> list[int]:
    finite = np.flatnonzero(
        np.all(np.isfinite(run.q), axis=1) & np.all(np.isfinite(run.position), axis=1)
    )
    if finite.size == 0:
        return []
    picks = np.linspace(0, finite.size - 1, min(count, finite.size)).round().astype(int)
    return [int(finite[i]) for i in np.unique(picks)]


def fit_planar_arm(runs: Sequence[StoredRun]) -> Robot:
    """A :class:`~otmm_qp.robots.planar_arm.PlanarArm` whose kinematics reproduce the runs.

    Raises:
        ConfigError: No positive link lengths reproduce the stored positions.
    """
    from otmm_qp.robots.planar_arm import PlanarArm

    blocks, targets = [], []
    for run in runs:
        rows = np.all(np.isfinite(run.q), axis=1) & np.all(np.isfinite(run.position), axis=1)
        theta = np.cumsum(run.q[rows], axis=1)
        blocks += [np.cos(theta), np.sin(theta)]
        targets += [run.position[rows, 0], run.position[rows, 1]]
    if not blocks or sum(b.shape[0] for b in blocks) == 0:
        raise ConfigError(str(runs[0].path), "no finite step to recover the planar arm from")
    matrix, target = np.vstack(blocks), np.concatenate(targets)
    lengths = np.linalg.lstsq(matrix, target, rcond=None)[0]
    residual = float(np.max(np.abs(matrix @ lengths - target)))
    if residual > MATCH_TOLERANCE * max(1.0, float(np.abs(target).max())) or np.any(lengths <= 0):
        raise ConfigError(
            str(runs[0].path.parent.parent / ROBOT_JSON),
            "cannot recover the planar arm's link lengths from the stored positions "
            f"(residual {residual:.2g} m); write this robot.json with the config's robot block",
        )
    return PlanarArm(lengths)


def _frame_matching(arm: Any, run: StoredRun, rows: Sequence[int]) -> str | None:
    """Name of a frame of ``arm`` that sits on the stored positions, or None."""
    import pinocchio as pin

    model, data = arm.model, arm.model.createData()
    worst = np.zeros(model.nframes)
    for k in rows:
        pin.framesForwardKinematics(model, data, arm.configuration(run.q[k]))
        points = np.array([data.oMf[i].translation for i in range(model.nframes)])
        worst = np.maximum(worst, np.linalg.norm(points - run.position[k], axis=1))
    matching = [str(model.frames[int(i)].name) for i in np.flatnonzero(worst <= MATCH_TOLERANCE)]
    if not matching:
        return None
    return arm.frame_name if arm.frame_name in matching else matching[-1]


def identify_urdf_arm(runs: Sequence[StoredRun]) -> Robot:
    """The example-robot-data arm (and frame) that produced the runs.

    Raises:
        ConfigError: No known arm has these joint names and kinematics.
    """
    from otmm_qp.robots.pinocchio_arm import ARMS, PinocchioArm

    run = runs[0]
    rows = _sample_rows(run)
    for name in sorted(ARMS):
        try:
            arm = PinocchioArm(name=name, task="position")
        except OtmmError:
            continue
        if arm.joint_names != run.joint_names or not rows:
            continue
        frame = _frame_matching(arm, run, rows)
        if frame is not None:
            return PinocchioArm(name=name, frame=frame, task="position")
    raise ConfigError(
        str(run.path.parent.parent / ROBOT_JSON),
        f"no example-robot-data arm ({', '.join(sorted(ARMS))}) has joints "
        f"{', '.join(run.joint_names)} and these end-effector positions; write this robot.json "
        'with the config\'s robot block, e.g. {"type": "pinocchio", "params": {"urdf": "..."}}',
    )


def load_robot(runs: Sequence[StoredRun]) -> Robot:
    """The robot of one experiment's runs (see the module docstring for the order).

    Raises:
        ConfigError: A malformed ``robot.json`` or an unidentifiable robot.
        OtmmError: The recorded robot cannot be built (e.g. its URDF moved).
    """
    from otmm_qp.runner.build import captured_stderr

    experiment_dir = runs[0].path.parent.parent
    results = ResultsDir(experiment_dir.parent)
    spec = results.read_robot_record(experiment_dir)
    if spec is not None:
        field = str(results.robot_json(experiment_dir))
        robot = _recorded_robot(spec, field)
        check_reproduces(robot, runs, field)
        return robot
    if runs[0].dimension == 2:
        return fit_planar_arm(runs)
    with captured_stderr():  # urdfdom lines are dropped when no arm matches
        return identify_urdf_arm(runs)


#: Largest stored-vs-recomputed position mismatch accepted for a recorded robot [m, relative
#: to max(1 m, the largest coordinate)]: the CSVs keep 9 significant digits.
RECORD_TOLERANCE = 1.0e-5


def _recorded_robot(spec: dict[str, Any], field: str) -> Robot:
    """The robot a ``robot.json`` record (:meth:`ResultsDir.read_robot_record`) describes.

    Built as a config's robot block is.

    Raises:
        ConfigError: Parameters the robot refuses, naming ``field``.
    """
    from otmm_qp.config.schema import PluginConfig
    from otmm_qp.runner.build import load_robot as build_robot

    return build_robot(PluginConfig(type=spec["type"], **spec["params"]), f"{field}: robot")


def check_reproduces(robot: Robot, runs: Sequence[StoredRun], field: str) -> None:
    r"""Require ``robot`` to put its task point on the stored positions of ``runs``.

    Checks up to 8 finite steps per run: :math:`\max_k \|f(q_k)_{1..d} - x_k\|_\infty \le`
    :data:`RECORD_TOLERANCE` :math:`\cdot \max(1, \max_k \|x_k\|_\infty)`.

    Raises:
        ConfigError: Another joint count, non-finite or mismatching kinematics.
    """
    worst, scale = 0.0, 1.0
    for run in runs:
        if run.q.shape[1] != robot.nv:
            raise ConfigError(
                field,
                f"describes a robot with {robot.nv} joints; {run.path.name} has {run.q.shape[1]}",
            )
        d = run.dimension
        for k in _sample_rows(run):
            with np.errstate(all="ignore"):
                x = np.asarray(robot.forward(joint_configuration(robot, run.q[k])), dtype=float)
            point = x[:3, 3] if x.ndim == 2 else x.ravel()  # a pose task gives a 4x4 transform
            if point.size < d or not np.all(np.isfinite(point[:d])):
                raise ConfigError(field, "its kinematics are not finite at the stored joints")
            worst = max(worst, float(np.max(np.abs(point[:d] - run.position[k]))))
            scale = max(scale, float(np.max(np.abs(run.position[k]))))
    if worst > RECORD_TOLERANCE * scale:
        raise ConfigError(
            field,
            f"does not reproduce the stored end-effector positions (off by {worst:.3g} m); "
            "it must be the robot block of the config that wrote these runs",
        )


def joint_configuration(robot: Robot, coordinates: FloatArray) -> FloatArray:
    """Configuration ``q`` of the robot for stored joint coordinates (manifold-aware)."""
    convert = getattr(robot, "configuration", None)
    if convert is None:
        return np.asarray(coordinates, dtype=float)
    return np.asarray(convert(np.asarray(coordinates, dtype=float)))


def record_robots(results_dir: Path, robots: dict[str, tuple[str, dict[str, Any]]]) -> list[Path]:
    """Write ``robot.json`` into the folder of each experiment's stored runs.

    Args:
        results_dir: The results folder.
        robots: Experiment display name → ``(robot type, params)`` (the config's robot block).

    Returns:
        The files written (experiments without stored runs are skipped).
    """
    results = ResultsDir(results_dir)
    folders: dict[str, Path] = {}
    for run in results.run_files():
        folders.setdefault(run.experiment, run.experiment_dir)
    return [
        results.write_robot_record(folders[name], robot_type, params)
        for name, (robot_type, params) in robots.items()
        if name in folders
    ]
