"""Peer adapter: pink (Pinocchio-based differential IK) on the same Pinocchio model."""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
import pinocchio as pin

from otmm_qp.backends.backend import BackendOutput
from otmm_qp.interrupt import sigint_held
from otmm_qp.robots.peer_models import PinocchioPeerModel
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.robots.velocity_task import VelocityTaskData
from otmm_qp.state import KinematicState
from otmm_qp.status import Status

from .peer_backend import QpPeerBackend, peer_limits, shrunk_limits

#: The warning ``pink.Configuration.check_limits`` logs on the root logger on every step whose
#: configuration is beyond a limit by more than 1e-6 (``safety_break=False``).
PINK_LIMIT_WARNING = "Value %f at index %d is out of limits: [%f, %f]"


class _DropPinkLimitWarnings(logging.Filter):
    """Drops :data:`PINK_LIMIT_WARNING` records; every other record passes.

    The harness counts limit violations itself (metrics); pink's one line per step flooded a
    study's terminal (52 lines in the first minutes of the arms study).
    """

    def filter(self, record: logging.LogRecord) -> bool:
        return record.msg != PINK_LIMIT_WARNING


_PINK_FILTER = _DropPinkLimitWarnings()


class PinkBackend(QpPeerBackend):
    r"""``pink.solve_ik`` with one velocity-level frame task, configuration and velocity limits.

    Each step pink solves (``Δq = q̇·dt``, ``e = −ẋ·dt``, ``W`` the task weight, ``J`` the
    commanded rows of the world-aligned frame Jacobian; see
    :mod:`otmm_qp.robots.velocity_task`) — ``qp``'s problem with ``λ = μ``, ``g`` the position gain:

    .. math::
        \min_{\Delta q}\ \|W(J\Delta q + e)\|^2 + \mu\|\Delta q\|^2
        \quad\text{s.t. configuration (gain g) and velocity limits}

    The model is the one the robot's peer description gives (a :class:`PinocchioArm`'s own
    reduced ``pin.Model``) or one parsed from the description's URDF (e.g. the URDF generated
    for a :class:`PlanarArm`); see :class:`~otmm_qp.robots.peer_models.PinocchioPeerModel`.

    Args:
        solver: qpsolvers backend name, e.g. ``daqp``, ``proxqp``, ``osqp``, ``quadprog``.
        damping: λ ≥ 0 [task units], the meaning of ``damping`` in every backend: pink's
            Tikhonov weight is μ = λ².
        regularization: Pink's Tikhonov weight μ ≥ 0 itself [cost]/[rad²] (instead of
            ``damping``); 10⁻¹² when neither is given.
        lm_damping: Levenberg–Marquardt damping ≥ 0 of the frame task.
        limits: The ``limits`` list of ``qp`` restricted to ``velocity`` (pink's
            ``VelocityLimit``, the model's speed limits capped by ``max_speed``) and
            ``position`` (``ConfigurationLimit`` with ``gain``); ``true`` / None: both, gain
            0.5; ``false``: none.

    Raises:
        PeerUnavailable: pink is not installed.
        SolverNotFound: ``solver`` is not an installed qpsolvers backend.
        ParameterError: A damping is negative.
    """

    name = "pink"
    peer = "pink"
    modules = ("pink",)

    def bind(self, robot: Robot, dt: float) -> None:
        """Build pink's configuration, velocity task and limits for ``robot`` (``dt`` in [s]).

        The model is a copy of the robot's whose position and speed limits are the robot's
        effective ones (overrides included), so pink's limits are the limits ``qp`` sees.
        """
        import pink
        from pink.limits import ConfigurationLimit, VelocityLimit

        super().bind(robot, dt)
        logging.getLogger().addFilter(_PINK_FILTER)  # idempotent: a filter is added once
        self._solve_ik = pink.solve_ik
        self._pinocchio = PinocchioPeerModel.create(self.description, robot)
        limits = peer_limits(self.limit_set, robot, dt)
        model = limited_model(self._pinocchio.model, robot, limits.speed, limits.margin)
        frame_id = self._pinocchio.frame_id
        self._model = model
        self._frame = str(model.frames[frame_id].name)
        self._configuration = pink.Configuration(model, model.createData(), pin.neutral(model))
        self._data = VelocityTaskData(self.task_rows)
        self._task = _pink_velocity_task(frame_id, self._data, self.lm_damping)
        self._limits: list[Any] = []  # both read the limits limited_model wrote into the model
        if limits.gain is not None:
            self._limits.append(ConfigurationLimit(model, config_limit_gain=limits.gain))
        if limits.speed is not None:
            self._limits.append(VelocityLimit(model))

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Pink's joint velocity [rad/s], shape ``(nv,)``, for the commanded velocity."""
        from pink.exceptions import PinkError

        configuration = self._configuration
        configuration.update(self._pinocchio.configuration(self.robot, state.q))
        self._data.set_command(self.physical_velocity(state, xdot), state.weight, self.dt)
        try:
            with sigint_held():  # a C solver's own SIGINT handler (OSQP's) would eat Ctrl-C
                velocity = self._solve_ik(
                    configuration,
                    [self._task],
                    self.dt,
                    solver=self.solver,
                    damping=self.regularization,
                    limits=self._limits,
                    safety_break=False,
                )
        except PinkError:
            return BackendOutput(np.zeros(self.robot.nv), Status.INFEASIBLE)
        return BackendOutput(self._pinocchio.velocity(velocity), Status.OK)


def limited_model(
    model: Any, robot: Robot, speeds: FloatArray | None = None, margin: float = 0.0
) -> Any:
    """A copy of ``model`` with the robot's effective position and speed limits written in.

    Args:
        model: The peer's ``pin.Model``.
        robot: The robot (its position limits, overrides included).
        speeds: The speed limits [rad/s], shape ``(nv,)``; the robot's when None.
        margin: Distance [rad] kept from each position limit (:func:`shrunk_limits`).
    """
    model = pin.Model(model)
    lower, upper = shrunk_limits(robot, margin)
    speeds = robot.velocity_limits if speeds is None else speeds
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
