"""Peer adapter: mink (MuJoCo-based differential IK) on an MJCF/URDF model of the same arm."""

from __future__ import annotations

from typing import Any

import numpy as np

from otmm_qp.backends.backend import STATUS_INFEASIBLE, STATUS_OK, BackendOutput
from otmm_qp.exceptions import PeerModelMismatch
from otmm_qp.peers.models import mujoco_joint_map, mujoco_model, pose_mismatch
from otmm_qp.peers.peer_backend import PeerBackend, require
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState

#: Largest Pinocchio/MuJoCo end-effector disagreement accepted at bind time [m] and [rad].
POSE_TOLERANCE = 1e-9


class MinkBackend(PeerBackend):
    r"""``mink.solve_ik`` with one site ``FrameTask``, configuration and velocity limits.

    .. math::
        \min_{\Delta q}\ \|J\Delta q + e\|_{W}^2 + \mu\|\Delta q\|^2
        \quad\text{s.t. configuration and velocity limits}, \qquad \dot q = \Delta q/dt

    The MuJoCo model is generated (:func:`~otmm_qp.peers.models.planar_mjcf`, in radians)
    for a planar arm or loaded from the arm's URDF with ``package://`` paths rewritten
    (:func:`~otmm_qp.peers.models.mujoco_model`). At :meth:`bind` Pinocchio and MuJoCo must
    agree on the end-effector pose at the joint-limit midpoint (or 0.3 rad per joint when
    unbounded) within :data:`POSE_TOLERANCE`.

    Args:
        solver: qpsolvers backend name (``daqp``, ``proxqp``, ``osqp``, ...).
        damping: Tikhonov weight μ ≥ 0 of mink's ``solve_ik``.
        lm_damping: Levenberg–Marquardt damping ≥ 0 of the frame task.
        limits: Enforce configuration and velocity limits.

    Raises:
        PeerUnavailable: mink or mujoco is not installed.
        SolverNotFound: ``solver`` is not an installed qpsolvers backend.
        ParameterError: A damping is negative.
    """

    name = "mink"
    peer = "mink"

    def __init__(
        self,
        solver: str = "daqp",
        damping: float = 1e-12,
        lm_damping: float = 0.0,
        limits: bool = True,
    ) -> None:
        require("mink", ["mujoco", "mink"])
        self.configure_qp(solver, damping, lm_damping, limits)

    def bind(self, robot: Robot, dt: float) -> None:
        """Build the MuJoCo model, check it against Pinocchio, set up task and limits.

        Raises:
            PeerModelMismatch: Pinocchio and MuJoCo disagree on the end-effector pose.
        """
        import mink

        super().bind(robot, dt)
        lower, upper = robot.position_limits
        bounded = np.isfinite(lower) & np.isfinite(upper)
        probe = np.full(robot.nv, 0.3)  # [rad]
        probe[bounded] = 0.5 * (lower[bounded] + upper[bounded])
        e_p, e_r = pose_mismatch(robot, probe)
        if e_p > POSE_TOLERANCE or e_r > POSE_TOLERANCE:
            raise PeerModelMismatch("mink", e_p, e_r)
        model, site = mujoco_model(robot)
        self._mink = mink
        self._site = site
        self._map = mujoco_joint_map(robot, model)
        self._qpos0 = np.array(model.qpos0)
        self._configuration = mink.Configuration(model)
        self._task = mink.FrameTask(
            site,
            "site",
            position_cost=1.0,
            orientation_cost=self.orientation_weight(),
            lm_damping=self.lm_damping,
        )
        self._limits: list[Any] = []
        if self.use_limits:
            speeds = {
                name: float(v)
                for name, v in zip(robot.joint_names, robot.velocity_limits, strict=True)
                if np.isfinite(v)
            }
            self._limits = [mink.ConfigurationLimit(model)]
            if speeds:
                self._limits.append(mink.VelocityLimit(model, speeds))

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Mink's joint velocity [rad/s], shape ``(nv,)``, toward the advanced target."""
        mink = self._mink
        configuration = self._configuration
        theta = self.robot.joint_coordinates(state.q)
        configuration.update(self._map.to_peer(theta, self._qpos0))
        pose = configuration.get_transform_frame_to_world(self._site, "site").as_matrix()
        linear, angular = self.spatial_velocity(self.robot, self.physical_velocity(state, xdot))
        target = self.advanced_pose(pose, linear, angular, self.dt)
        self._task.set_target(mink.SE3.from_matrix(target))
        try:
            velocity = mink.solve_ik(
                configuration,
                [self._task],
                self.dt,
                self.solver,
                damping=self.damping,
                limits=self._limits,
            )
        except mink.MinkError:
            return BackendOutput(np.zeros(self.robot.nv), STATUS_INFEASIBLE)
        return BackendOutput(self._map.from_peer_velocity(velocity), STATUS_OK)
