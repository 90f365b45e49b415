"""Peer adapter: mink (MuJoCo-based differential IK) on an MJCF/URDF model of the same arm."""

from __future__ import annotations

from typing import Any

import numpy as np

from otmm_qp.backends.backend import BackendOutput
from otmm_qp.exceptions import PeerModelMismatch
from otmm_qp.interrupt import sigint_held
from otmm_qp.robots.peer_models import (
    JointMap,
    PinocchioPeerModel,
    model_mismatch,
    mujoco_joint_map,
    mujoco_model,
)
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.robots.velocity_task import VelocityTaskData
from otmm_qp.state import KinematicState
from otmm_qp.status import Status

from .peer_backend import QpPeerBackend, peer_limits, shrunk_limits

#: Largest Pinocchio/MuJoCo end-effector disagreement accepted at bind time [m] and [rad].
POSE_TOLERANCE = 1e-9


class MinkBackend(QpPeerBackend):
    r"""``mink.solve_ik`` with one velocity-level site task, configuration and velocity limits.

    .. math::
        \min_{\Delta q}\ \|W(J\Delta q + e)\|^2 + \mu\|\Delta q\|^2
        \quad\text{s.t. configuration (gain g) and velocity limits}, \qquad \dot q = \Delta q/dt

    with ``e = −ẋ·dt`` and ``J`` the commanded rows of the site's world-aligned Jacobian
    (:mod:`otmm_qp.robots.velocity_task`): ``qp``'s problem with ``λ = μ``. The MuJoCo model's
    joint ranges are the robot's effective limits (overrides included).

    The MuJoCo model is the MJCF of the robot's peer description when it has one (planar
    arms: :func:`~otmm_qp.robots.planar_arm.planar_mjcf`, in radians) or loaded from the
    description's URDF with ``package://`` paths rewritten
    (:func:`~otmm_qp.robots.peer_models.mujoco_model`). At :meth:`bind` Pinocchio and MuJoCo must
    agree on the end-effector pose at the joint-limit midpoint (or 0.3 rad per joint when
    unbounded) within :data:`POSE_TOLERANCE`.

    Args:
        solver: qpsolvers backend name (``daqp``, ``proxqp``, ``osqp``, ...).
        damping: λ ≥ 0 [task units], the meaning of ``damping`` in every backend: mink's
            Tikhonov weight is μ = λ².
        regularization: Mink's Tikhonov weight μ ≥ 0 itself (instead of ``damping``);
            10⁻¹² when neither is given.
        lm_damping: Levenberg–Marquardt damping ≥ 0 of the frame task.
        limits: The ``limits`` list of ``qp`` restricted to ``velocity`` (mink's
            ``VelocityLimit``) and ``position`` (``ConfigurationLimit`` with ``gain``);
            ``true`` / None: both, gain 0.5; ``false``: none.

    Raises:
        PeerUnavailable: mink or mujoco is not installed.
        SolverNotFound: ``solver`` is not an installed qpsolvers backend.
        ParameterError: A damping is negative.
    """

    name = "mink"
    peer = "mink"
    modules = ("mujoco", "mink")

    def bind(self, robot: Robot, dt: float) -> None:
        """Build the MuJoCo model, check it against Pinocchio, set up task and limits.

        Raises:
            PeerModelMismatch: Pinocchio and MuJoCo disagree on the end-effector pose.
        """
        import mink

        super().bind(robot, dt)
        pinocchio = PinocchioPeerModel.create(self.description, robot)
        model, site = mujoco_model(self.description, (pinocchio.model, pinocchio.frame_id))
        lower, upper = robot.position_limits
        bounded = np.isfinite(lower) & np.isfinite(upper)
        probe = np.full(robot.nv, 0.3)  # [rad]
        probe[bounded] = 0.5 * (lower[bounded] + upper[bounded])
        e_p, e_r = model_mismatch(robot, pinocchio, (model, site), probe)
        if e_p > POSE_TOLERANCE or e_r > POSE_TOLERANCE:
            raise PeerModelMismatch("mink", e_p, e_r)
        self._mink = mink
        self._site = site
        self._map = mujoco_joint_map(robot, model)
        limits = peer_limits(self.limit_set, robot, dt)
        write_position_limits(model, robot, self._map, limits.margin)
        self._qpos0 = np.array(model.qpos0)
        self._configuration = mink.Configuration(model)
        self._data = VelocityTaskData(self.task_rows)
        self._task = _mink_velocity_task(site, self._data, self.lm_damping)
        self._limits: list[Any] = []
        if limits.gain is not None:
            self._limits.append(mink.ConfigurationLimit(model, gain=limits.gain))
        if limits.speed is not None:
            speeds = {
                name: float(v)
                for name, v in zip(robot.joint_names, limits.speed, strict=True)
                if np.isfinite(v)
            }
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
        self._data.set_command(self.physical_velocity(state, xdot), state.weight, self.dt)
        try:
            with sigint_held():  # a C solver's own SIGINT handler (OSQP's) would eat Ctrl-C
                velocity = mink.solve_ik(
                    configuration,
                    [self._task],
                    self.dt,
                    self.solver,
                    damping=self.regularization,
                    limits=self._limits,
                )
        except mink.MinkError:
            return BackendOutput(np.zeros(self.robot.nv), Status.INFEASIBLE)
        return BackendOutput(self._map.from_peer_velocity(velocity), Status.OK)


def write_position_limits(
    model: Any, robot: Robot, joint_map: JointMap, margin: float = 0.0
) -> None:
    """Write the robot's effective position limits, shrunk by ``margin`` [rad], into ``model``.

    Overrides included; the margin as in :func:`~.peer_backend.shrunk_limits`.
    """
    import mujoco

    lower, upper = shrunk_limits(robot, margin)
    for index, name in enumerate(robot.joint_names):
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        bounded = bool(np.isfinite(lower[index]) and np.isfinite(upper[index]))
        model.jnt_limited[jid] = int(bounded)
        if bounded:
            model.jnt_range[jid] = [lower[index], upper[index]]


def _mink_velocity_task(site: str, data: VelocityTaskData, lm_damping: float) -> Any:
    """A mink ``Task`` with ``e = −ẋ·dt`` and ``J = S·J_LWA`` (see :mod:`velocity_task`)."""
    import mujoco
    from mink.tasks import Task

    class MinkVelocityTask(Task):
        def __init__(self) -> None:
            super().__init__(cost=data.cost, lm_damping=lm_damping)
            self._site_id: int | None = None

        def compute_error(self, configuration: Any) -> FloatArray:
            return data.error

        def compute_jacobian(self, configuration: Any) -> FloatArray:
            model = configuration.model
            if self._site_id is None:
                self._site_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
            jacobian = np.empty((6, model.nv))
            mujoco.mj_jacSite(model, configuration.data, jacobian[:3], jacobian[3:], self._site_id)
            return jacobian[data.rows]

    return MinkVelocityTask()
