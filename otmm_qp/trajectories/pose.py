r"""Pose trajectories in SE(3): a 3-D line or circle for the position, slerp for the rotation.

Poses are 4×4 homogeneous matrices; velocities are twists ``(6,)`` = linear velocity of the
frame origin [m/s] then angular velocity [rad/s], both in world axes (the convention of
:class:`~otmm_qp.robots.pinocchio_arm.PinocchioArm` and its ``LOCAL_WORLD_ALIGNED``
Jacobian).

Orientation targets are given either as ``end_rpy = [roll, pitch, yaw]`` [rad] (fixed
axes X, then Y, then Z: :math:`R = R_z(y)R_y(p)R_x(r)`) or as ``end_quaternion = [x, y, z,
w]`` (scalar last, normalised here). Without either, the start orientation is kept.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from numbers import Real
from typing import ClassVar, Literal

import numpy as np

from otmm_qp.exceptions import ConfigError, DimensionError, ParameterError
from otmm_qp.robots.robot import FloatArray
from otmm_qp.trajectories.circle import CircleTrajectory
from otmm_qp.trajectories.trajectory import Trajectory
from otmm_qp.validation import ArrayOf, Constraints, Interval, OneOf, check_params

Profile = Literal["quintic", "constant"]


def _skew(w: FloatArray) -> FloatArray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def exp_so3(w: FloatArray) -> FloatArray:
    r"""Rotation matrix :math:`\exp([w]_\times)` (Rodrigues), ``w`` [rad], shape ``(3,)``."""
    angle = float(np.linalg.norm(w))
    K = _skew(w)
    if angle < 1e-8:
        return np.eye(3) + K + 0.5 * K @ K
    return np.eye(3) + (np.sin(angle) / angle) * K + ((1.0 - np.cos(angle)) / angle**2) * K @ K


def log_so3(R: FloatArray) -> FloatArray:
    r"""Rotation vector ``w`` [rad] with :math:`\exp([w]_\times) = R`, ``|w| ≤ π``."""
    import pinocchio as pin

    return np.asarray(pin.log3(np.asarray(R, dtype=float)))


def rpy_matrix(rpy: Sequence[float]) -> FloatArray:
    """``R = R_z(yaw) R_y(pitch) R_x(roll)`` from ``[roll, pitch, yaw]`` [rad]."""
    r, p, y = (float(v) for v in rpy)
    return (
        exp_so3(np.array([0.0, 0.0, y]))
        @ exp_so3(np.array([0.0, p, 0.0]))
        @ exp_so3(np.array([r, 0.0, 0.0]))
    )


def quaternion_matrix(quaternion: Sequence[float]) -> FloatArray:
    """Rotation matrix of the quaternion ``[x, y, z, w]`` (normalised first)."""
    x, y, z, w = np.asarray(quaternion, dtype=float) / np.linalg.norm(quaternion)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _start_pose(start: FloatArray) -> FloatArray:
    pose = np.asarray(start, dtype=float)
    if pose.shape != (4, 4):
        raise DimensionError("start", (4, 4), pose.shape)
    return pose.copy()


class _Orientation:
    r"""Slerp from ``R0`` to ``R1``: :math:`R(s) = R_0\exp(s\,[\omega_b]_\times)`.

    With :math:`\omega_b = \log(R_0^\top R_1)` the world angular velocity is
    :math:`\dot s\,R_0\,\omega_b` (constant direction).
    """

    def __init__(
        self,
        R0: FloatArray,
        end_rpy: Sequence[float] | None,
        end_quaternion: Sequence[float] | None,
    ) -> None:
        if end_rpy is not None and end_quaternion is not None:
            raise ConfigError("end_rpy", "give at most one of end_rpy and end_quaternion")
        self.R0 = R0
        if end_rpy is not None:
            if np.shape(end_rpy) != (3,):
                raise DimensionError("end_rpy", (3,), np.shape(end_rpy))
            R1 = rpy_matrix(end_rpy)
        elif end_quaternion is not None:
            if np.shape(end_quaternion) != (4,):
                raise DimensionError("end_quaternion", (4,), np.shape(end_quaternion))
            if not np.linalg.norm(end_quaternion) > 0.0:
                raise ParameterError("end_quaternion", "must be a nonzero [x, y, z, w]")
            R1 = quaternion_matrix(end_quaternion)
        else:
            R1 = R0
        self.R1 = R1
        self.body_rotation = log_so3(R0.T @ R1)  # ω_b [rad]
        self.world_rotation = R0 @ self.body_rotation  # [rad]

    def at(self, s: float, ds: float) -> tuple[FloatArray, FloatArray]:
        """Rotation at path parameter ``s`` and world angular velocity for ``ṡ`` [1/s]."""
        return self.R0 @ exp_so3(s * self.body_rotation), ds * self.world_rotation

    def rotations(self, s: FloatArray) -> FloatArray:
        r"""Rotations at path parameters ``s``, shape ``(m, 3, 3)``, at once.

        With :math:`\omega_b = \theta u` (``|u| = 1``) and :math:`K = [u]_\times`,
        :math:`R_0\exp(s\theta K) = R_0 + \sin(s\theta)\,R_0K + (1 − \cos(s\theta))\,R_0K^2`
        (Rodrigues about the fixed axis); ``θ < 1e-8``: ``R_0``.
        """
        angle = float(np.linalg.norm(self.body_rotation))
        out = np.broadcast_to(self.R0, (s.shape[0], 3, 3)).copy()
        if angle >= 1e-8:
            K = _skew(self.body_rotation / angle)
            first, second = self.R0 @ K, self.R0 @ K @ K
            out += np.sin(s * angle)[:, None, None] * first
            out += (1.0 - np.cos(s * angle))[:, None, None] * second
        return out


def _time_law(t: float, duration: float, profile: str) -> tuple[float, float]:
    """Path parameter ``s ∈ [0, 1]`` and ``ṡ`` [1/s]; held at the ends outside ``[0, T]``."""
    tau = min(max(t / duration, 0.0), 1.0)
    moving = 0.0 <= t <= duration
    if profile == "quintic":
        s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)
        ds = 30.0 * tau**2 * (1.0 - tau) ** 2 / duration
    else:
        s, ds = tau, 1.0 / duration
        moving = 0.0 <= t < duration
    return s, (ds if moving else 0.0)


class PoseLineTrajectory(Trajectory):
    r"""Straight line for the position, slerp for the orientation, one shared time law.

    .. math::
        p(t) = p_0 + s(t)(p_1 - p_0),\qquad R(t) = R_0\exp(s(t)\log(R_0^\top R_1)),\qquad
        \dot x = (\dot s\,(p_1 - p_0),\ \dot s\,R_0\log(R_0^\top R_1))

    with ``s = 10τ³ − 15τ⁴ + 6τ⁵`` (``quintic``) or ``s = τ`` (``constant``), ``τ = t/T``,
    held at the end pose for ``t > T``.

    Args:
        start: Start pose, shape ``(4, 4)``.
        end: End position [m], shape ``(3,)``; the start position when omitted.
        duration: Motion time ``T`` [s], > 0.
        end_rpy: End orientation ``[roll, pitch, yaw]`` [rad] (see module doc).
        end_quaternion: End orientation ``[x, y, z, w]``.
        profile: ``quintic`` or ``constant``.
    """

    #: A planned motion: known in full at any time (:attr:`Trajectory.lookahead`).
    lookahead = math.inf

    name = "pose_line"

    parameter_constraints: ClassVar[Constraints] = {
        "duration": Interval(Real, 0, None, closed="neither", unit="s"),
        "end": [ArrayOf(Interval(Real, None, None, unit="m"), length=3, per="coordinate"), None],
        "end_rpy": [
            ArrayOf(Interval(Real, None, None, unit="rad"), length=3, per="roll, pitch, yaw"),
            None,
        ],
        "end_quaternion": [
            ArrayOf(Interval(Real, None, None), length=4, per="x, y, z, w (normalised here)"),
            None,
        ],
        "profile": OneOf("quintic", "constant"),
    }

    def __init__(
        self,
        start: FloatArray,
        duration: float,
        end: Sequence[float] | None = None,
        end_rpy: Sequence[float] | None = None,
        end_quaternion: Sequence[float] | None = None,
        profile: Profile = "quintic",
    ) -> None:
        check_params(self, locals())
        pose = _start_pose(start)
        if not duration > 0.0:
            raise ParameterError("duration", f"must be > 0 [s], got {duration}")
        if profile not in ("quintic", "constant"):
            raise ParameterError("profile", f"must be quintic or constant, got {profile!r}")
        self.begin = pose[:3, 3].copy()
        self.end = self.begin.copy() if end is None else np.asarray(end, dtype=float)
        if self.end.shape != (3,):
            raise DimensionError("end", (3,), self.end.shape)
        self.duration = float(duration)
        self.profile = profile
        self.orientation = _Orientation(pose[:3, :3], end_rpy, end_quaternion)

    def sample(self, t: float) -> tuple[FloatArray, FloatArray]:
        """Pose ``(4, 4)`` and twist ``(6,)`` [m/s, rad/s] at ``t`` [s]."""
        s, ds = _time_law(t, self.duration, self.profile)
        pose = np.eye(4)
        twist = np.empty(6)
        delta = self.end - self.begin
        pose[:3, 3] = self.begin + s * delta
        pose[:3, :3], twist[3:] = self.orientation.at(s, ds)
        twist[:3] = ds * delta
        return pose, twist

    def positions(self, times: Sequence[float]) -> list[FloatArray]:
        """Poses ``(4, 4)`` at each of ``times`` [s], evaluated at once (:meth:`sample`'s law)."""
        tau = np.clip(np.asarray(times, dtype=float) / self.duration, 0.0, 1.0)
        s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2) if self.profile == "quintic" else tau
        poses = np.zeros((tau.shape[0], 4, 4))
        poses[:, 3, 3] = 1.0
        poses[:, :3, 3] = self.begin + s[:, None] * (self.end - self.begin)
        poses[:, :3, :3] = self.orientation.rotations(s)
        return list(poses)


class PoseCircleTrajectory(Trajectory):
    r"""3-D circle for the position (see :class:`CircleTrajectory`), slerp for the rotation.

    .. math::
        p(t) = c + r(\cos\phi\,e_1 + \sin\phi\,e_2),\qquad
        R(t) = R_0\exp(\tfrac{t}{T}\log(R_0^\top R_1)),\quad T = \text{turns}\cdot\text{period}

    Position and orientation share one time law over the natural duration ``T``: ``quintic``
    (default; the circle angle and the slerp parameter follow ``s = 10τ³ − 15τ⁴ + 6τ⁵``, so
    the motion starts and ends at rest) or ``constant`` (constant speed, a velocity jump at
    ``t = 0``). After ``T`` the end pose is held (position and orientation).

    Args:
        start: Start pose, shape ``(4, 4)``.
        centre: Circle centre [m], shape ``(3,)``.
        radius: Radius [m], > 0.
        period: Time for one turn [s], > 0.
        direction: ``clockwise`` or ``counterclockwise`` seen from +normal.
        start_angle: φ₀ [rad]; the circle point nearest to the start position when omitted.
        normal: Plane normal (default +z).
        turns: Number of turns in the natural duration.
        end_rpy: End orientation ``[roll, pitch, yaw]`` [rad].
        end_quaternion: End orientation ``[x, y, z, w]``.
        profile: ``quintic`` (smooth start and stop, default) or ``constant``.
    """

    #: A planned motion: known in full at any time (:attr:`Trajectory.lookahead`).
    lookahead = math.inf

    name = "pose_circle"

    parameter_constraints: ClassVar[Constraints] = {
        "centre": ArrayOf(Interval(Real, None, None, unit="m"), length=3, per="coordinate"),
        "radius": Interval(Real, 0, None, closed="neither", unit="m"),
        "period": Interval(Real, 0, None, closed="neither", unit="s"),
        "direction": OneOf("clockwise", "counterclockwise"),
        "start_angle": [Interval(Real, None, None, unit="rad"), None],
        "normal": [ArrayOf(Interval(Real, None, None), length=3, per="coordinate"), None],
        "turns": Interval(Real, 0, None, closed="neither"),
        "end_rpy": [
            ArrayOf(Interval(Real, None, None, unit="rad"), length=3, per="roll, pitch, yaw"),
            None,
        ],
        "end_quaternion": [
            ArrayOf(Interval(Real, None, None), length=4, per="x, y, z, w (normalised here)"),
            None,
        ],
        "profile": OneOf("quintic", "constant"),
    }

    def __init__(
        self,
        start: FloatArray,
        centre: Sequence[float],
        radius: float,
        period: float,
        direction: Literal["clockwise", "counterclockwise"] = "clockwise",
        start_angle: float | None = None,
        normal: Sequence[float] | None = None,
        turns: float = 1.0,
        end_rpy: Sequence[float] | None = None,
        end_quaternion: Sequence[float] | None = None,
        profile: Profile = "quintic",
    ) -> None:
        check_params(self, locals())
        pose = _start_pose(start)
        if np.shape(centre) != (3,):
            raise DimensionError("centre", (3,), np.shape(centre))
        if profile not in ("quintic", "constant"):
            raise ParameterError("profile", f"must be quintic or constant, got {profile!r}")
        self.profile = profile
        self.circle = CircleTrajectory(
            pose, centre, radius, period, direction, start_angle, normal, turns, profile
        )
        self.duration = self.circle.duration
        self.orientation = _Orientation(pose[:3, :3], end_rpy, end_quaternion)

    def sample(self, t: float) -> tuple[FloatArray, FloatArray]:
        """Pose ``(4, 4)`` and twist ``(6,)`` [m/s, rad/s] at ``t`` [s]."""
        held = min(t, self.duration)  # the end pose is held after T
        position, velocity = self.circle.sample(held)
        if t > self.duration:
            velocity = 0.0 * velocity
        s, ds = _time_law(t, self.duration, self.profile)
        pose = np.eye(4)
        twist = np.empty(6)
        pose[:3, 3] = position
        pose[:3, :3], twist[3:] = self.orientation.at(s, ds)
        twist[:3] = velocity
        return pose, twist
