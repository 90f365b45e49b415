r"""Peer adapter: OInK (``roboplan-oink``, C++ QP differential IK with Python bindings).

OInK solves, per step, for the joint displacement ``Δq = q̇·dt`` of a joint group

.. math::
    \min_{\Delta q}\ \|W(e(T^*) - J\Delta q)\|^2 + \mu\|\Delta q\|^2
    \quad\text{s.t.}\quad \text{position limits (gain g)},\ |\Delta q| \le \dot q_{max}\,dt

with its ``FrameTask``: ``e(T*)`` the SE(3) error of the end-effector frame to the target
``T*`` (:meth:`~.peer_backend.PeerBackend.advanced_pose`: the pose one period along the
commanded twist), ``W = diag(√cost)`` from ``FrameTaskOptions(position_cost,
orientation_cost)``. With ``cost = w²`` per row (``w`` the step's task weight, uniform over the
position rows and over the orientation rows) this is ``qp``'s problem (``μ`` the same) up to
the SE(3) log of one period's motion, O(dt²). A position task has orientation cost 0; a planar
arm's target keeps its plane.

The model is the one pink, mink and Drake use: the peer description's URDF
(:func:`~otmm_qp.robots.peer_models.peer_urdf`: joints the robot locks are fixed, no geometry)
with the robot's effective position limits (shrunk by a ``predicted_position`` margin) and
speed limits written into it, in an OInK joint group of the robot's joints.

OInK 0.7.0 has no σ_min / manipulability barrier (its barriers are ``PositionBarrier``, a
frame in a box, and ``SelfCollisionBarrier``), so otmm-qp's ``singularity_barrier`` has no
counterpart and is refused like any other limit the peers cannot express.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from numbers import Real
from typing import Any, ClassVar

import numpy as np

from otmm_qp.backends.backend import BackendOutput, damping_weight
from otmm_qp.exceptions import ParameterError
from otmm_qp.limits import LimitSpec
from otmm_qp.robots.peer_models import peer_urdf
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.status import Status
from otmm_qp.validation import Constraints, Interval, check_params

from .peer_backend import (
    DEFAULT_REGULARIZATION,
    PEER_LIMIT_CONSTRAINTS,
    PEER_REMOVED,
    PeerBackend,
    peer_limits,
    require,
    shrunk_limits,
)

#: The name of the OInK joint group of the robot's joints.
GROUP = "otmm"
#: ProxQP's absolute tolerance here (OInK's default 1e-6 let joints pass their limits by up to
#: 8e-6 rad in a 40-task arms slice, 1e-9 by 2e-9 rad; daqp in ``qp`` stops near 1e-10).
EPS_ABS = 1e-11

_NON_NEGATIVE = Interval(Real, 0, None, closed="left")


class OinkBackend(PeerBackend):
    """``Oink.solveIk`` with one ``FrameTask``, ``PositionLimit`` and ``VelocityLimit``.

    See the module docstring for the problem and how it maps onto ``qp``'s.

    Args:
        damping: λ ≥ 0 [task units]: OInK's Tikhonov weight is μ = λ².
        regularization: μ ≥ 0 itself instead of ``damping``; 10⁻¹² when neither is given.
        lm_damping: Levenberg–Marquardt damping ≥ 0 of the frame task.
        limits: The ``limits`` list of ``qp`` restricted to ``velocity`` (OInK's
            ``VelocityLimit``), ``position`` / ``predicted_position`` (OInK's ``PositionLimit``
            with ``gain``, the margin written into the model's limits); ``true`` / None: the
            default set; ``false``: none.

    Raises:
        PeerUnavailable: roboplan-oink is not installed (with the install hint).
        ParameterError: A damping out of range, or a limit OInK has no counterpart of.
    """

    name = "oink"
    peer = "oink"
    parameter_constraints: ClassVar[Constraints] = {
        "damping": [_NON_NEGATIVE, None],
        "regularization": [_NON_NEGATIVE, None],
        "lm_damping": _NON_NEGATIVE,
        **PEER_LIMIT_CONSTRAINTS,
    }
    removed_parameters: ClassVar[Mapping[str, str]] = PEER_REMOVED

    def __init__(
        self,
        damping: float | None = None,
        regularization: float | None = None,
        lm_damping: float = 0.0,
        limits: bool | Sequence[LimitSpec] | None = None,
    ) -> None:
        check_params(self, locals())
        require(self.peer, ["roboplan.optimal_ik"])
        self.regularization = damping_weight(damping, regularization, DEFAULT_REGULARIZATION)
        self.lm_damping = float(lm_damping)
        self.configure_limits(limits)

    def bind(self, robot: Robot, dt: float) -> None:
        """Build OInK's scene, joint group, limits and the index map for ``robot``."""
        import roboplan.core as core
        import roboplan.optimal_ik as oink

        super().bind(robot, dt)
        description = self.description
        limits = peer_limits(self.limit_set, robot, dt)
        speeds = robot.velocity_limits if limits.speed is None else limits.speed
        urdf = _limited_urdf(
            peer_urdf(description, keep_geometry=False),
            description.joint_names,
            shrunk_limits(robot, limits.margin),
            np.asarray(speeds, dtype=float),
        )
        scene = core.Scene("otmm", core.loadUrdfSceneDescriptionFromXml(urdf, []))
        scene.addGroup(GROUP, list(description.joint_names))
        self._core, self._oink = core, oink
        self._scene = scene
        settings = oink.OinkSettings()
        settings.eps_abs = EPS_ABS
        self._solver = oink.Oink(scene, GROUP, settings)
        self._index = np.asarray(scene.getJointPositionIndices(list(description.joint_names)))
        self._q = np.array(scene.getCurrentJointPositions(), dtype=float)
        self._delta = np.zeros(self._solver.num_variables)
        self._constraints: list[Any] = []
        if limits.gain is not None:
            self._constraints.append(oink.PositionLimit(self._solver, limits.gain))
        if limits.speed is not None:
            finite = np.where(np.isfinite(limits.speed), limits.speed, 1e12)
            self._constraints.append(oink.VelocityLimit(self._solver, dt, finite))
        self._task: Any = None
        self._costs: tuple[float, float] | None = None

    def reset(self) -> None:
        """Forget the task (rebuilt at the next step)."""
        self._task = None
        self._costs = None

    def _frame_task(self, weight: FloatArray) -> Any:
        """The ``FrameTask`` with costs ``w²`` (rebuilt when the step's weight changes).

        Raises:
            ParameterError: The weight differs within the position or the orientation rows
                (OInK has one cost per block).
        """
        rows = self.task_rows
        position = weight[rows < 3]
        orientation = weight[rows >= 3]
        for block, values in (("position", position), ("orientation", orientation)):
            if values.size and not np.all(values == values[0]):
                raise ParameterError(
                    "task_weight",
                    f"oink takes one {block} cost: the {block} rows' weights must be equal, "
                    f"got {values.tolist()}",
                )
        costs = (
            float(position[0]) ** 2 if position.size else 0.0,
            float(orientation[0]) ** 2 if orientation.size else 0.0,
        )
        if self._task is None or costs != self._costs:
            options = self._oink.FrameTaskOptions(
                position_cost=costs[0],
                orientation_cost=costs[1],
                task_gain=1.0,
                lm_damping=self.lm_damping,
            )
            target = self._core.CartesianConfiguration(
                "", self.description.frame, np.asfortranarray(np.eye(4))
            )
            self._task = self._oink.FrameTask(self._solver, self._scene, target, options)
            self._costs = costs
        return self._task

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """OInK's joint velocity [rad/s], shape ``(nv,)``, for the commanded velocity."""
        task = self._frame_task(np.asarray(state.weight, dtype=float))
        q = self._q
        q[self._index] = self.robot.joint_coordinates(state.q)
        pose = self._scene.forwardKinematics(q, self.description.frame)
        linear, angular = self.spatial_velocity(self.physical_velocity(state, xdot))
        target = self.advanced_pose(np.asarray(pose), linear, angular, self.dt)
        task.setTargetFrameTransform(np.asfortranarray(target))
        delta = self._delta
        try:
            self._solver.solveIk(q, [task], self._constraints, delta, self.regularization)
        except RuntimeError:
            return BackendOutput(np.zeros(self.robot.nv), Status.INFEASIBLE)
        if not np.all(np.isfinite(delta)):
            return BackendOutput(np.zeros(self.robot.nv), Status.INFEASIBLE)
        return BackendOutput(delta / self.dt, Status.OK)


def _limited_urdf(
    urdf: str,
    joint_names: Sequence[str],
    bounds: tuple[FloatArray, FloatArray],
    speeds: FloatArray,
) -> str:
    """``urdf`` with each named joint's ``<limit>`` set to ``bounds`` [rad] and ``speeds``."""
    root = ET.fromstring(urdf)
    lower, upper = bounds
    joints = {joint.get("name"): joint for joint in root.findall("joint")}  # not <transmission>s
    for i, name in enumerate(joint_names):
        joint = joints[name]
        limit = joint.find("limit")
        if limit is None:
            limit = ET.SubElement(joint, "limit", effort="1")
        if np.isfinite(lower[i]) and np.isfinite(upper[i]) and joint.get("type") != "continuous":
            limit.set("lower", repr(float(lower[i])))
            limit.set("upper", repr(float(upper[i])))
        limit.set("velocity", repr(float(speeds[i]) if np.isfinite(speeds[i]) else 1e12))
    return ET.tostring(root, encoding="unicode")
