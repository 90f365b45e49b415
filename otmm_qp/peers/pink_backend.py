"""Peer adapter: pink (Pinocchio-based differential IK) on the same Pinocchio model."""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from otmm_qp.backends.backend import STATUS_INFEASIBLE, STATUS_OK, BackendOutput
from otmm_qp.peers.models import pinocchio_model
from otmm_qp.peers.peer_backend import PeerBackend, require
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState


class PinkBackend(PeerBackend):
    r"""``pink.solve_ik`` with one ``FrameTask``, configuration and velocity limits.

    Each step pink solves (``Δq = q̇·dt``, ``e`` the frame task error toward the advanced
    target pose, see :mod:`otmm_qp.peers.peer_backend`):

    .. math::
        \min_{\Delta q}\ \|J\Delta q + e\|_{W}^2 + \mu\|\Delta q\|^2
        \quad\text{s.t. configuration and velocity limits}

    The model is the robot's own: a :class:`PinocchioArm`'s reduced ``pin.Model``, or the
    URDF generated from a :class:`PlanarArm` (:func:`~otmm_qp.peers.models.planar_urdf`).

    Args:
        solver: qpsolvers backend name, e.g. ``daqp``, ``proxqp``, ``osqp``, ``quadprog``.
        damping: Tikhonov weight μ ≥ 0 of pink's ``solve_ik`` [cost]/[rad²].
        lm_damping: Levenberg–Marquardt damping ≥ 0 of the frame task.
        limits: Enforce configuration and velocity limits.

    Raises:
        PeerUnavailable: pink is not installed.
        SolverNotFound: ``solver`` is not an installed qpsolvers backend.
        ParameterError: A damping is negative.
    """

    name = "pink"
    peer = "pink"

    def __init__(
        self,
        solver: str = "daqp",
        damping: float = 1e-12,
        lm_damping: float = 0.0,
        limits: bool = True,
    ) -> None:
        require("pink", ["pink"])
        self.configure_qp(solver, damping, lm_damping, limits)

    def bind(self, robot: Robot, dt: float) -> None:
        """Build pink's configuration, frame task and limits for ``robot`` (``dt`` in [s])."""
        import pink
        from pink.limits import ConfigurationLimit, VelocityLimit

        super().bind(robot, dt)
        self._solve_ik = pink.solve_ik
        model, frame_id = pinocchio_model(robot)
        self._model = model
        self._frame = str(model.frames[frame_id].name)
        self._planar = isinstance(robot, PlanarArm)
        self._configuration = pink.Configuration(model, model.createData(), pin.neutral(model))
        self._task = pink.tasks.FrameTask(
            self._frame,
            position_cost=1.0,
            orientation_cost=self.orientation_weight(),
            lm_damping=self.lm_damping,
        )
        self._limits: list[Any] = []
        if self.use_limits:
            self._limits = [
                ConfigurationLimit(model),
                VelocityLimit(model, velocity_limit=np.asarray(robot.velocity_limits)),
            ]

    def _pin_configuration(self, q: FloatArray) -> FloatArray:
        if self._planar:  # generated model: continuous joints are (cos, sin) pairs
            return np.asarray(pin.integrate(self._model, pin.neutral(self._model), q))
        return np.asarray(q, dtype=float)

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Pink's joint velocity [rad/s], shape ``(nv,)``, toward the advanced target."""
        from pink.exceptions import PinkError

        configuration = self._configuration
        configuration.update(self._pin_configuration(state.q))
        pose = configuration.get_transform_frame_to_world(self._frame).homogeneous
        linear, angular = self.spatial_velocity(self.robot, self.physical_velocity(state, xdot))
        target = self.advanced_pose(pose, linear, angular, self.dt)
        self._task.set_target(pin.SE3(target))
        try:
            velocity = self._solve_ik(
                configuration,
                [self._task],
                self.dt,
                solver=self.solver,
                damping=self.damping,
                limits=self._limits,
                safety_break=False,
            )
        except PinkError:
            return BackendOutput(np.zeros(self.robot.nv), STATUS_INFEASIBLE)
        return BackendOutput(np.asarray(velocity, dtype=float), STATUS_OK)
