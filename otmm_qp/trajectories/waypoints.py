r"""Waypoint trajectories: piecewise quintic segments in task space or in joint space.

Each segment goes from rest to rest with the quintic (minimum-jerk) law
:math:`s(\tau) = 10\tau^3 - 15\tau^4 + 6\tau^5`, :math:`\tau = (t - t_i)/T_i`, so velocity
and acceleration are continuous (zero) at every waypoint. After the last segment the end
value is held.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from numbers import Real
from typing import Any, ClassVar

import numpy as np

from otmm_qp.exceptions import ConfigError, DimensionError, ParameterError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.trajectories.pose import exp_so3, log_so3, rpy_matrix
from otmm_qp.trajectories.trajectory import Trajectory
from otmm_qp.validation import ArrayOf, Boolean, Constraints, InstanceOf, Interval, check_params


def quintic(tau: float) -> tuple[float, float]:
    """Quintic law ``s(τ)`` and ``ds/dτ`` for ``τ`` clipped to ``[0, 1]``."""
    tau = min(max(tau, 0.0), 1.0)
    return tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2), 30.0 * tau**2 * (1.0 - tau) ** 2


class _Segments:
    """Segment timing: durations ``T_i`` [s] and the segment containing a time."""

    def __init__(self, lengths: Sequence[float], duration: float | None, durations: Any) -> None:
        count = len(lengths)
        if durations is not None:
            values = np.asarray(durations, dtype=float)
            if values.shape != (count,):
                raise DimensionError("segment_durations", (count,), values.shape)
            if not np.all(values > 0.0):
                raise ParameterError("segment_durations", "every duration must be > 0 [s]")
        else:
            if duration is None or not duration > 0.0:
                raise ParameterError("duration", f"must be > 0 [s], got {duration}")
            weights = np.asarray(lengths, dtype=float)
            total = float(weights.sum())
            # Time shared in proportion to segment length (equal shares for zero length).
            weights = weights / total if total > 0.0 else np.full(count, 1.0 / count)
            weights = np.maximum(weights, 1e-3)
            values = duration * weights / weights.sum()
        self.durations = values
        self.starts = np.concatenate(([0.0], np.cumsum(values)[:-1]))
        self.duration = float(values.sum())

    def locate(self, t: float) -> tuple[int, float, float]:
        """Segment index ``i``, path parameter ``s`` and ``ṡ`` [1/s] at ``t`` [s]."""
        if t >= self.duration:
            return len(self.durations) - 1, 1.0, 0.0
        i = max(0, int(np.searchsorted(self.starts, t, side="right")) - 1)
        length = float(self.durations[i])
        s, ds = quintic((t - float(self.starts[i])) / length)
        return i, s, (ds / length if t >= 0.0 else 0.0)


class WaypointsTrajectory(Trajectory):
    r"""Task-space waypoints from the start value, piecewise quintic.

    Position tasks: :math:`x(t) = P_i + s(t)(P_{i+1} - P_i)` on segment ``i``. Pose tasks:
    the same for the position and :math:`R(t) = R_i\exp(s\log(R_i^\top R_{i+1}))` for the
    orientation, twist :math:`(\dot s (P_{i+1} - P_i),\ \dot s R_i\log(R_i^\top R_{i+1}))`.

    Args:
        start: Task value at the start configuration: a point ``(d,)`` or a pose ``(4, 4)``.
        waypoints: Points after the start, each ``[x, y(, z)]`` [m]; for pose tasks also
            ``[x, y, z, roll, pitch, yaw]`` [m, rad] (3 values keep the previous orientation).
        duration: Total motion time [s], shared in proportion to segment lengths.
        segment_durations: Time of each segment [s] instead of ``duration``.
        return_to_start: Append the start value as a last waypoint.
    """

    #: A planned motion: known in full at any time (:attr:`Trajectory.lookahead`).
    lookahead = math.inf

    name = "waypoints"

    parameter_constraints: ClassVar[Constraints] = {
        "waypoints": InstanceOf(
            (list, tuple),
            "a list of points [x, y(, z)] [m] (pose: + roll, pitch, yaw [rad])",
            exclude=(str,),
        ),
        "duration": [Interval(Real, 0, None, closed="neither", unit="s"), None],
        "segment_durations": [
            ArrayOf(Interval(Real, 0, None, closed="neither", unit="s"), per="segment"),
            None,
        ],
        "return_to_start": Boolean(),
    }

    def __init__(
        self,
        start: FloatArray,
        waypoints: Sequence[Sequence[float]],
        duration: float | None = None,
        segment_durations: Sequence[float] | None = None,
        return_to_start: bool = False,
    ) -> None:
        check_params(self, locals())
        value = np.asarray(start, dtype=float)
        self.is_pose = value.shape == (4, 4)
        dim = 3 if self.is_pose else value.size
        if len(waypoints) == 0:
            raise ConfigError("waypoints", "give at least one waypoint")
        begin = value[:3, 3].copy() if self.is_pose else value.copy()
        rotation = value[:3, :3].copy() if self.is_pose else np.eye(3)
        points = [begin]
        rotations = [rotation]
        for j, raw in enumerate(waypoints):
            entry = np.asarray(raw, dtype=float)
            allowed = (3, 6) if self.is_pose else (dim,)
            if entry.ndim != 1 or entry.size not in allowed:
                raise DimensionError(f"waypoints.{j}", (allowed[-1],), entry.shape)
            if not np.all(np.isfinite(entry)):
                raise ParameterError(f"waypoints.{j}", "must be finite")
            points.append(entry[:dim].copy())
            rotations.append(rpy_matrix(entry[3:6].tolist()) if entry.size == 6 else rotations[-1])
        if return_to_start:
            points.append(begin.copy())
            rotations.append(rotation.copy())
        self.points = np.array(points)
        self.rotations = rotations
        self.body_rotations = [
            log_so3(a.T @ b) if self.is_pose else np.zeros(3)
            for a, b in zip(rotations, rotations[1:], strict=False)
        ]
        lengths = np.linalg.norm(np.diff(self.points, axis=0), axis=1) + np.array(
            [np.linalg.norm(w) for w in self.body_rotations]
        )
        self.segments = _Segments(list(lengths), duration, segment_durations)
        self.duration = self.segments.duration

    def sample(self, t: float) -> tuple[FloatArray, FloatArray]:
        """Task value and velocity at ``t`` [s] (pose: ``(4, 4)`` and twist ``(6,)``)."""
        i, s, ds = self.segments.locate(t)
        delta = self.points[i + 1] - self.points[i]
        position = self.points[i] + s * delta
        if not self.is_pose:
            return position, ds * delta
        pose = np.eye(4)
        pose[:3, 3] = position
        body = self.body_rotations[i]
        pose[:3, :3] = self.rotations[i] @ exp_so3(s * body)
        twist = np.concatenate((ds * delta, ds * (self.rotations[i] @ body)))
        return pose, twist


class JointWaypointsTrajectory(Trajectory):
    r"""Joint-space waypoints, piecewise quintic; the task reference is their forward kinematics.

    .. math::
        q(t) = Q_i + s(t)(Q_{i+1} - Q_i),\qquad x_d(t) = f(q(t)),\qquad
        \dot x_d(t) = J(q(t))\,\dot q(t)

    (``J`` in the robot's convention, so ``ẋ_d`` is the exact derivative of ``x_d``).

    In a config only ``waypoints`` and the timing are given: the experiment passes its robot
    and ``q0``, and the first waypoint must be ``q0`` (a motion starting elsewhere would jump
    there in one step).

    Args:
        start: Task value at the start configuration (unused: the first waypoint is the start).
        robot: The arm (a :class:`Robot`, or a ``{type: NAME, **params}`` robot record).
        waypoints: Joint coordinates ``(nv,)`` [rad or m], the first being the start
            configuration ``q0``; at least two.
        duration: Total motion time [s], shared in proportion to joint-space segment lengths.
        segment_durations: Time of each segment [s] instead of ``duration``.
        return_to_start: Append the first waypoint as a last one.
        q0: The experiment's start configuration ``(nq,)``, or None (not checked); the first
            waypoint must equal it (to 1e-9 rad or m per joint, continuous joints modulo 2π).

    Raises:
        ConfigError: Fewer than two waypoints, or a first waypoint that is not ``q0``.
    """

    #: A planned motion: known in full at any time (:attr:`Trajectory.lookahead`).
    lookahead = math.inf

    name = "joint_waypoints"

    parameter_constraints: ClassVar[Constraints] = {
        "waypoints": InstanceOf(
            (list, tuple),
            "a list of joint coordinate lists [rad or m], the first being q0",
            exclude=(str,),
        ),
        "duration": [Interval(Real, 0, None, closed="neither", unit="s"), None],
        "segment_durations": [
            ArrayOf(Interval(Real, 0, None, closed="neither", unit="s"), per="segment"),
            None,
        ],
        "return_to_start": Boolean(),
    }
    framework_parameters = ("start", "robot", "q0")

    def __init__(
        self,
        start: FloatArray,
        robot: Robot | Mapping[str, Any],
        waypoints: Sequence[Sequence[float]],
        duration: float | None = None,
        segment_durations: Sequence[float] | None = None,
        return_to_start: bool = False,
        q0: FloatArray | None = None,
    ) -> None:
        check_params(self, locals())
        if not isinstance(robot, Robot):
            from otmm_qp import registry

            spec = dict(robot)
            if "type" not in spec:
                raise ConfigError("robot", "give {type: NAME, ...} of a registered robot")
            kind = str(spec.pop("type"))
            robot = registry.create(registry.ROBOTS, kind, spec, "robot")
        assert isinstance(robot, Robot)
        self.robot = robot
        nodes = [np.asarray(w, dtype=float) for w in waypoints]
        if len(nodes) < 2:
            raise ConfigError("waypoints", "give at least two joint waypoints (start first)")
        for j, node in enumerate(nodes):
            if node.shape != (robot.nv,):
                raise DimensionError(f"waypoints.{j}", (robot.nv,), node.shape)
            if not np.all(np.isfinite(node)):
                raise ParameterError(f"waypoints.{j}", "must be finite")
        if q0 is not None:
            _check_first_waypoint(robot, nodes[0], np.asarray(q0, dtype=float))
        if return_to_start:
            nodes.append(nodes[0].copy())
        self.nodes = np.array(nodes)
        lengths = np.linalg.norm(np.diff(self.nodes, axis=0), axis=1)
        self.segments = _Segments(list(lengths), duration, segment_durations)
        self.duration = self.segments.duration

    def joint_sample(self, t: float) -> tuple[FloatArray, FloatArray]:
        """Joint coordinates [rad] and joint velocity [rad/s] at ``t`` [s], shapes ``(nv,)``."""
        i, s, ds = self.segments.locate(t)
        delta = self.nodes[i + 1] - self.nodes[i]
        return self.nodes[i] + s * delta, ds * delta

    def sample(self, t: float) -> tuple[FloatArray, FloatArray]:
        """Task value ``f(q(t))`` and velocity ``J q̇`` at ``t`` [s]."""
        coordinates, qdot = self.joint_sample(t)
        x, jacobian = self.robot.kinematics(self.robot.configuration(coordinates))
        return np.array(x, copy=True), jacobian @ qdot


def _check_first_waypoint(robot: Robot, first: FloatArray, q0: FloatArray) -> None:
    """Refuse a first waypoint other than ``q0`` (compared as joint coordinates, 1e-9)."""
    start = robot.joint_coordinates(q0)
    given = robot.joint_coordinates(robot.configuration(first))
    if not np.allclose(given, start, rtol=0.0, atol=1e-9):
        shown = ", ".join(f"{v:.4g}" for v in start)
        jump = float(np.max(np.abs(given - start)))
        raise ConfigError(
            "waypoints.0",
            f"must be the start configuration q0 = [{shown}] (the motion starts there; "
            f"this one is {jump:.3g} rad away, a jump in one step)",
        )
