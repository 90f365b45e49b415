r"""Shared machinery of the peer adapters: availability checks and the task-velocity target.

A peer library solves differential IK toward a *target pose*, not a task velocity. Each
step the adapter turns the commanded task velocity :math:`\dot x` into the target the
peer would have reached after one period :math:`dt` if it realised :math:`\dot x` exactly:

.. math::
    p^* = p + v\,dt, \qquad R^* = \exp(\omega\,dt)\,R

(world-aligned linear velocity ``v`` of the frame origin [m/s] and angular velocity ``ω``
[rad/s], the convention of :class:`~otmm_qp.robots.pinocchio_arm.PinocchioArm`; a position
task has ``ω = 0`` and no orientation cost). The peer's joint step ``Δq`` toward that target
gives the joint velocity ``q̇ = Δq/dt``.

Which rows of ``(v, ω)`` the task commands comes from the robot's
:class:`~otmm_qp.robots.peer_description.PeerDescription` (asked once, in :meth:`PeerBackend.bind`)
and its ``task_kind``, never from the robot's class.
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from otmm_qp.backends.backend import Backend
from otmm_qp.exceptions import ParameterError, PeerUnavailable, SolverNotFound
from otmm_qp.peers.models import describe
from otmm_qp.peers.velocity_task import task_rows
from otmm_qp.robots.peer_description import PeerDescription
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState

#: ``pip install`` hint shown when a peer is missing.
INSTALL_HINTS: dict[str, str] = {
    "pink": 'pip install "otmm-qp[peers]"  (or: pip install pin-pink)',
    "mink": 'pip install "otmm-qp[peers]"  (or: pip install mink mujoco)',
    "drake": 'pip install "otmm-qp[peers]"  (or: pip install drake)',
}


def require(peer: str, modules: Sequence[str]) -> None:
    """Import ``modules`` or raise :class:`PeerUnavailable` with the install hint.

    Raises:
        PeerUnavailable: One of the modules cannot be imported.
    """
    for module in modules:
        try:
            importlib.import_module(module)
        except ImportError as error:
            raise PeerUnavailable(
                peer, f"{INSTALL_HINTS[peer]} (import {module!r} failed: {error})"
            ) from error


def check_limit_gain(limit_gain: float) -> float:
    """``limit_gain`` as a float in (0, 1] (the position-limit gain ``g`` of ``qp``).

    Raises:
        ParameterError: Outside (0, 1] or not finite.
    """
    if not (np.isfinite(limit_gain) and 0.0 < limit_gain <= 1.0):
        raise ParameterError("limit_gain", f"must be in (0, 1], got {limit_gain}")
    return float(limit_gain)


class PeerBackend(Backend):
    """A backend that delegates each step to a third-party IK library.

    Subclasses import their library in ``__init__`` (via :func:`require`, so a missing peer
    becomes :class:`PeerUnavailable` before the run starts), build the peer's model in
    :meth:`bind` (after ``super().bind``, from :attr:`description`) and implement
    :meth:`solve`.

    Attributes:
        description: The robot's checked peer description (set by :meth:`bind`).
        task_rows: Rows of the frame twist ``(v, ω)`` the task commands, shape ``(n,)``.
    """

    #: Peer library name (``pink``, ``mink``, ``drake``).
    peer: str = "peer"

    def bind(self, robot: Robot, dt: float) -> None:
        """Attach the robot and ask it, once, for its :class:`PeerDescription`.

        Raises:
            RobotLoadError: The robot cannot describe itself to a peer, or its description
                does not match it (see :func:`~otmm_qp.peers.models.describe`).
        """
        super().bind(robot, dt)
        self.description: PeerDescription = describe(robot)
        self.task_rows: np.ndarray = task_rows(self.description.planar, robot.task_kind)

    @staticmethod
    def physical_velocity(state: KinematicState, xdot: FloatArray) -> FloatArray:
        r"""Un-weighted task velocity :math:`\dot x = W^{-1}\dot x_w`, shape ``(n,)``."""
        return np.asarray(xdot, dtype=float) / state.weight

    def spatial_velocity(self, xdot: FloatArray) -> tuple[FloatArray, FloatArray]:
        """World-aligned ``(v [m/s], ω [rad/s])``, shapes ``(3,)``, of a task velocity ``(n,)``.

        Planar: ``v = (ẋ, ẏ, 0)``; position tasks: ``ω = 0``; pose tasks: ``(v, ω)``.
        """
        twist = np.zeros(6)
        twist[self.task_rows] = xdot
        return twist[:3], twist[3:]

    @staticmethod
    def advanced_pose(
        pose: FloatArray, linear: FloatArray, angular: FloatArray, dt: float
    ) -> FloatArray:
        r"""Target ``T*`` (4, 4): :math:`p^* = p + v\,dt,\ R^* = \exp(\omega\,dt) R`."""
        target = np.array(pose, dtype=float)
        target[:3, 3] += linear * dt
        target[:3, :3] = pin.exp3(angular * dt) @ target[:3, :3]
        return target

    def configure_qp(
        self, solver: str, damping: float, lm_damping: float, limits: bool, limit_gain: float
    ) -> None:
        """Validate and store the settings shared by the QP-based peers (pink, mink).

        Raises:
            SolverNotFound: ``solver`` is not an installed qpsolvers backend.
            ParameterError: A damping is negative or not finite, or ``limit_gain`` is not in
                (0, 1].
        """
        import qpsolvers

        if solver not in qpsolvers.available_solvers:
            raise SolverNotFound(solver, qpsolvers.available_solvers)
        for field, value in (("damping", damping), ("lm_damping", lm_damping)):
            if not (np.isfinite(value) and value >= 0.0):
                raise ParameterError(field, f"must be a finite number >= 0, got {value}")
        self.solver = solver
        self.damping = float(damping)
        self.lm_damping = float(lm_damping)
        self.use_limits = bool(limits)
        self.limit_gain = check_limit_gain(limit_gain)

    def orientation_weight(self) -> float:
        """1 when the task commands the angular velocity (pose tasks), else 0."""
        return 1.0 if bool(np.any(self.task_rows >= 3)) else 0.0
