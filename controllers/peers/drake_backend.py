"""Peer adapter: Drake's ``DoDifferentialInverseKinematics`` on the same URDF, base welded."""

from __future__ import annotations

import importlib
import logging
from collections.abc import Mapping, Sequence
from numbers import Real
from typing import Any, ClassVar

import numpy as np

from otmm_qp.backends.backend import BackendOutput
from otmm_qp.limits import LimitSpec
from otmm_qp.robots.peer_description import PeerDescription
from otmm_qp.robots.peer_models import JointMap, peer_urdf, pinocchio_model, root_link
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.status import Status
from otmm_qp.validation import Constraints, Interval, check_params

from .peer_backend import (
    PEER_LIMIT_CONSTRAINTS,
    PEER_REMOVED,
    PeerBackend,
    peer_limits,
    require,
    shrunk_limits,
)

#: Name of the frame added at the end effector of the Drake plant.
DRAKE_FRAME = "otmm_ee"


class DrakeBackend(PeerBackend):
    r"""Drake's direction-preserving differential IK (``DoDifferentialInverseKinematics``).

    .. math::
        \max_{\dot q,\ \alpha}\ 100\,\alpha - \|P\dot q\|^2 \quad\text{s.t.}\quad
        J\dot q = \alpha V,\ 0 \le \alpha \le 1,\ \text{position and velocity limits}

    with ``V`` the commanded spatial velocity :math:`(\omega, v)` of the end-effector frame
    in world axes (the rows the task commands are selected by Drake's velocity flag: x, y
    for planar arms, the linear part for position tasks, all six for poses) and ``P`` a
    basis of the Jacobian null space. A tiny realisable fraction α is reported by Drake as
    ``stuck``; no solution as ``infeasible`` (zero joint speed).

    The plant is parsed from the URDF of the robot's peer description, rewritten by
    :func:`~otmm_qp.robots.peer_models.peer_urdf` (kinematics only), its root link welded to the
    world. The end-effector frame is added at the Pinocchio frame placement
    (:func:`~otmm_qp.robots.peer_models.pinocchio_model`).

    Args:
        stuck_scaling: α below which Drake reports ``stuck``, in ``[0, 1)``.
        limits: The ``limits`` list of ``qp`` restricted to ``velocity`` (Drake's joint
            velocity limits) and ``position``: for gain ``g`` Drake's position constraint
            ``θ_min ≤ θ + q̇·dt ≤ θ_max`` is given the limits ``θ ± g·(θ_max − θ)`` each step,
            so it bounds ``q̇`` by ``g(θ_max − θ)/dt`` as ``qp`` does; ``true`` / None: both,
            gain 0.5; ``false``: none.

    Raises:
        PeerUnavailable: pydrake is not installed.
        ParameterError: ``stuck_scaling`` out of range.
    """

    name = "drake"
    peer = "drake"
    parameter_constraints: ClassVar[Constraints] = {
        "stuck_scaling": Interval(Real, 0, 1, closed="left"),
        **PEER_LIMIT_CONSTRAINTS,
    }
    removed_parameters: ClassVar[Mapping[str, str]] = PEER_REMOVED

    def __init__(
        self,
        stuck_scaling: float = 0.01,
        limits: bool | Sequence[LimitSpec] | None = None,
    ) -> None:
        check_params(self, locals())
        require("drake", ["pydrake.multibody.inverse_kinematics", "pydrake.multibody.plant"])
        self.stuck_scaling = float(stuck_scaling)
        self.configure_limits(limits)

    def bind(self, robot: Robot, dt: float) -> None:
        """Parse the URDF into a ``MultibodyPlant`` and set up the DiffIK parameters."""
        # Drake's bundled stubs mistype numpy arguments; use the module untyped.
        ik: Any = importlib.import_module("pydrake.multibody.inverse_kinematics")

        super().bind(robot, dt)
        plant = _welded_plant(self.description)
        self._plant = plant
        self._context = plant.CreateDefaultContext()
        self._frame = plant.GetFrameByName(DRAKE_FRAME)
        joints = [plant.GetJointByName(name) for name in robot.joint_names]
        self._map = JointMap(
            np.array([j.position_start() for j in joints]),
            np.array([j.velocity_start() for j in joints]),
            plant.num_positions(),
        )
        self._q0 = plant.GetPositions(self._context).copy()
        parameters = ik.DifferentialInverseKinematicsParameters(
            plant.num_positions(), plant.num_velocities()
        )
        parameters.set_time_step(dt)
        limits = peer_limits(self.limit_set, robot, dt)
        self._gain = limits.gain
        lower, upper = shrunk_limits(robot, limits.margin)
        q_low = np.full(plant.num_positions(), -np.inf)
        q_high = np.full(plant.num_positions(), np.inf)
        self._limit_arrays = (q_low, q_high)
        self._lower, self._upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
        parameters.set_joint_position_limits((q_low, q_high))
        v_max = np.full(plant.num_velocities(), np.inf)
        if limits.speed is not None:
            v_max[self._map.velocity_index] = limits.speed
        parameters.set_joint_velocity_limits((-v_max, v_max))
        parameters.set_maximum_scaling_to_report_stuck(self.stuck_scaling)
        # Drake orders a twist (ωx, ωy, ωz, vx, vy, vz); our rows index (v, ω).
        self._twist_index = (self.task_rows + 3) % 6
        flags = np.zeros(6, dtype=bool)
        flags[self._twist_index] = True
        parameters.set_end_effector_velocity_flag(flags.tolist())
        self._parameters = parameters
        self._ik = ik
        self._status = ik.DifferentialInverseKinematicsStatus

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Drake's joint velocity [rad/s], shape ``(nv,)``, for the commanded velocity."""
        theta = self.robot.joint_coordinates(state.q)
        self._plant.SetPositions(self._context, self._map.to_peer(theta, self._q0))
        gain = self._gain
        if gain is not None:
            q_low, q_high = self._limit_arrays
            index = self._map.position_index
            q_low[index] = theta - gain * (theta - self._lower)  # ±inf stays ±inf
            q_high[index] = theta + gain * (self._upper - theta)
            self._parameters.set_joint_position_limits((q_low, q_high))
        twist = np.zeros(6)  # V_WE = (ω, v), world axes
        twist[self._twist_index] = self.physical_velocity(state, xdot)
        result = self._ik.DoDifferentialInverseKinematics(
            self._plant, self._context, twist, self._frame, self._parameters
        )
        if result.status == self._status.kNoSolutionFound or result.joint_velocities is None:
            return BackendOutput(np.zeros(self.robot.nv), Status.INFEASIBLE)
        qdot = self._map.from_peer_velocity(np.asarray(result.joint_velocities).ravel())
        status = Status.STUCK if result.status == self._status.kStuck else Status.OK
        return BackendOutput(qdot, status)


def _welded_plant(description: PeerDescription) -> Any:
    """A finalised ``MultibodyPlant`` of the arm, base welded, with :data:`DRAKE_FRAME` added.

    The end-effector frame sits at its Pinocchio placement on the parent joint's child body.
    """
    math: Any = importlib.import_module("pydrake.math")
    parsing: Any = importlib.import_module("pydrake.multibody.parsing")
    plants: Any = importlib.import_module("pydrake.multibody.plant")
    tree: Any = importlib.import_module("pydrake.multibody.tree")
    pin_model, frame_id = pinocchio_model(description)
    urdf = peer_urdf(description, keep_geometry=False)
    plant = plants.MultibodyPlant(time_step=0.0)
    # Drake warns once per URDF tag it ignores (safety_controller, a locked finger's mimic):
    # harmless for kinematics, and a page of noise before every run's output.
    drake_log = logging.getLogger("drake")
    level = drake_log.level
    drake_log.setLevel(logging.ERROR)
    try:
        parsing.Parser(plant).AddModelsFromString(urdf, "urdf")
    finally:
        drake_log.setLevel(level)
    base = root_link(urdf)
    if base != "world":  # Drake merges a URDF link named "world" into its world body
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(base))
    frame = pin_model.frames[frame_id]
    parent = str(pin_model.names[frame.parentJoint])
    body_frame = plant.GetJointByName(parent).child_body().body_frame()
    placement = math.RigidTransform(np.asarray(frame.placement.homogeneous))
    plant.AddFrame(tree.FixedOffsetFrame(DRAKE_FRAME, body_frame, placement))
    plant.Finalize()
    return plant
