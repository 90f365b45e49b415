"""Peer adapter: pink (Pinocchio-based differential IK) on the same Pinocchio model."""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from otmm_qp.backends.backend import STATUS_INFEASIBLE, STATUS_OK, BackendOutput
from otmm_qp.peers.models import pinocchio_model
from otmm_qp.peers.peer_backend import PeerBackend, require
from otmm_qp.peers.velocity_task import VelocityTaskData, task_rows
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState


class PinkBackend(PeerBackend):
    r"""``pink.solve_ik`` with one velocity-level frame task, configuration and velocity limits.

    Each step pink solves (``Δq = q̇·dt``, ``e = −ẋ·dt``, ``W`` the task weight, ``J`` the
    commanded rows of the world-aligned frame Jacobian; see
    :mod:`otmm_qp.peers.velocity_task`) — ``qp``'s problem with ``λ = μ``, ``g`` = ``limit_gain``:

    .. math::
        \min_{\Delta q}\ \|W(J\Delta q + e)\|^2 + \mu\|\Delta q\|^2
        \quad\text{s.t. configuration (gain g) and velocity limits}

    The model is the robot's own: a :class:`PinocchioArm`'s reduced ``pin.Model``, or the
    URDF generated from a :class:`PlanarArm` (:func:`~otmm_qp.peers.models.planar_urdf`).

    Args:
        solver: qpsolvers backend name, e.g. ``daqp``, ``proxqp``, ``osqp``, ``quadprog``.
        damping: Tikhonov weight μ ≥ 0 of pink's ``solve_ik`` [cost]/[rad²].
        lm_damping: Levenberg–Marquardt damping ≥ 0 of the frame task.
        limits: Enforce configuration and velocity limits.
        limit_gain: ``g ∈ (0, 1]`` of the configuration limits (``qp``'s ``limit_gain``).

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
        limit_gain: float = 0.5,
    ) -> None:
        require("pink", ["pink"])
        self.configure_qp(solver, damping, lm_damping, limits, limit_gain)

    def bind(self, robot: Robot, dt: float) -> None:
        """Build pink's configuration, velocity task and limits for ``robot`` (``dt`` in [s]).

        The model is a copy of the robot's whose position and speed limits are the robot's
        effective ones (overrides included), so pink's limits are the limits ``qp`` sees.
        """
        import pink
        from pink.limits import ConfigurationLimit, VelocityLimit

        super().bind(robot, dt)
        self._solve_ik = pink.solve_ik
        model, frame_id = pinocchio_model(robot)
        model = limited_model(model, robot)
        self._model = model
        self._frame = str(model.frames[frame_id].name)
        self._planar = isinstance(robot, PlanarArm)
        self._configuration = pink.Configuration(model, model.createData(), pin.neutral(model))
        self._data = VelocityTaskData(task_rows(robot))
        self._task = _pink_velocity_task(frame_id, self._data, self.lm_damping)
        self._limits: list[Any] = []
        if self.use_limits:
            self._limits = [
                ConfigurationLimit(model, config_limit_gain=self.limit_gain),
                VelocityLimit(model, velocity_limit=np.asarray(robot.velocity_limits)),
            ]

    def _pin_configuration(self, q: FloatArray) -> FloatArray:
        if self._planar:  # generated model: continuous joints are (cos, sin) pairs
            return np.asarray(pin.integrate(self._model, pin.neutral(self._model), q))
        return np.asarray(q, dtype=float)

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Pink's joint velocity [rad/s], shape ``(nv,)``, for the commanded velocity."""
        from pink.exceptions import PinkError

        configuration = self._configuration
        configuration.update(self._pin_configuration(state.q))
        self._data.set_command(self.physical_velocity(state, xdot), state.weight, self.dt)
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


def limited_model(model: Any, robot: Robot) -> Any:
    """A copy of ``model`` with the robot's effective position and speed limits written in."""
    model = pin.Model(model)
    lower, upper = robot.position_limits
    speeds = robot.velocity_limits
    for index, name in enumerate(robot.joint_names):
        joint = model.joints[model.getJointId(name)]
        if joint.nq == 1:  # revolute / prismatic; continuous joints stay unbounded
            model.lowerPositionLimit[joint.idx_q] = lower[index]
            model.upperPositionLimit[joint.idx_q] = upper[index]
        model.velocityLimit[joint.idx_v] = speeds[index]
    return model


def _pink_velocity_task(frame_id: int, data: VelocityTaskData, lm_damping: float) -> Any:
    """A pink ``Task`` with ``e = −ẋ·dt`` and ``J = S·J_LWA`` (see :mod:`velocity_task`)."""
    from pink.tasks import Task

    class PinkVelocityTask(Task):
        def __init__(self) -> None:
            super().__init__(cost=data.cost, lm_damping=lm_damping)

        def compute_error(self, configuration: Any) -> FloatArray:
            return data.error

        def compute_jacobian(self, configuration: Any) -> FloatArray:
            jacobian = pin.getFrameJacobian(
                configuration.model, configuration.data, frame_id, pin.LOCAL_WORLD_ALIGNED
            )
            return np.asarray(jacobian[data.rows])

        def __repr__(self) -> str:
            return f"PinkVelocityTask(frame={frame_id}, rows={data.rows.tolist()})"

    return PinkVelocityTask()
