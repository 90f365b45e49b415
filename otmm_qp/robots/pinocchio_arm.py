r"""Real serial arms through Pinocchio: example-robot-data models or any URDF.

The Jacobian is expressed in ``LOCAL_WORLD_ALIGNED``: its rows are the linear velocity
[m/s] of the end-effector frame *origin* and the angular velocity [rad/s], both in world
axes. The pose error of :meth:`PinocchioArm.task_error` uses the matching log map.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from numbers import Real
from typing import Any, ClassVar

import numpy as np
import pinocchio as pin

from otmm_qp.exceptions import DimensionError, FrameNotFound, ParameterError, RobotLoadError
from otmm_qp.robots.peer_description import PeerDescription
from otmm_qp.robots.robot import FloatArray, Robot, TaskKind
from otmm_qp.robots.urdf_meshes import check_meshes
from otmm_qp.validation import ArrayOf, Constraints, InstanceOf, Interval, OneOf


@dataclass(frozen=True)
class ArmDescription:
    """Where an example-robot-data arm lives and how it is reduced to an arm.

    Attributes:
        urdf: URDF path relative to the example-robot-data ``robots`` directory.
        frame: Default end-effector frame.
        locked: Joints locked at 0 (grippers) to keep only the arm.
    """

    urdf: str
    frame: str
    locked: tuple[str, ...] = ()


#: Supported example-robot-data arms. ``ur3`` is resolved to ``ur3_robot.urdf`` here because
#: ``example_robot_data.load("ur3")`` (5.0) maps the name to the UR5 loader.
ARMS: dict[str, ArmDescription] = {
    "kinova": ArmDescription("kinova_description/robots/kinova.urdf", "j2s6s200_end_effector"),
    "panda": ArmDescription(
        "panda_description/urdf/panda.urdf",
        "panda_hand_tcp",
        ("panda_finger_joint1", "panda_finger_joint2"),
    ),
    "ur10": ArmDescription("ur_description/urdf/ur10_robot.urdf", "tool0"),
    "ur3": ArmDescription("ur_description/urdf/ur3_robot.urdf", "tool0"),
    "ur5": ArmDescription("ur_description/urdf/ur5_robot.urdf", "tool0"),
    "xarm7": ArmDescription("xarm_description/urdf/xarm7.urdf", "link_eef"),
    "z1": ArmDescription("z1_description/urdf/z1.urdf", "gripperStator", ("jointGripper",)),
}

_TASK_DIMS = {"position": 3, "pose": 6}


def _example_robot_data_dir(relative_urdf: str) -> str:
    """Directory holding example-robot-data's ``*_description`` packages."""
    try:
        from example_robot_data.robots_loader import getModelPath
    except ImportError as error:  # pragma: no cover - a declared dependency
        raise RobotLoadError(
            f"name: example-robot-data is not installed ({error}); give a urdf path instead"
        ) from error
    try:
        return str(getModelPath(relative_urdf))
    except OSError as error:
        raise RobotLoadError(f"name: cannot locate {relative_urdf!r}: {error}") from error


@dataclass(frozen=True)
class _Source:
    """Where a model comes from: URDF path, robot name, default frame, locks, package dirs."""

    urdf_path: str
    name: str
    frame: str | None
    locked: dict[str, float | None]
    package_dirs: list[str]


def _resolve_source(
    name: str | None, urdf: str | None, package_dirs: Sequence[str] | None
) -> _Source:
    """The URDF of an example-robot-data ``name`` or of a ``urdf`` path.

    Raises:
        RobotLoadError: Both or neither given, unknown ``name``, or no file at the path.
    """
    if (name is None) == (urdf is None):
        raise RobotLoadError("robot: give exactly one of name (example-robot-data) or urdf")
    extra = [str(d) for d in package_dirs] if package_dirs is not None else []
    if name is not None:
        if name not in ARMS:
            raise RobotLoadError(
                f"name: unknown robot {name!r}; valid names: {', '.join(sorted(ARMS))}"
            )
        description = ARMS[name]
        robots_dir = _example_robot_data_dir(description.urdf)
        source = _Source(
            os.path.join(robots_dir, description.urdf),
            name,
            description.frame,
            dict.fromkeys(description.locked, 0.0),
            extra + [os.path.normpath(os.path.join(robots_dir, "..", ".."))],
        )
    else:
        path = os.path.abspath(os.path.expanduser(str(urdf)))
        source = _Source(path, os.path.splitext(os.path.basename(path))[0], None, {}, extra)
    if not os.path.isfile(source.urdf_path):
        raise RobotLoadError(f"urdf: file not found: {source.urdf_path}")
    return source


class PinocchioArm(Robot):
    r"""A fixed-base serial arm loaded with Pinocchio; task = frame position or pose.

    .. math::
        x = {}^{0}\!p_f(q) \in \mathbb{R}^3 \quad(\text{position}),\qquad
        x = {}^{0}T_f(q) \in SE(3) \quad(\text{pose, } 4\times4)

        J = \begin{bmatrix} {}^{0}\dot p_f \\ {}^{0}\omega_f \end{bmatrix}
        \Big/ \dot q \quad(\texttt{LOCAL\_WORLD\_ALIGNED}), \qquad
        e = \begin{bmatrix} p^* - p \\ \log_{SO(3)}(R^* R^\top) \end{bmatrix}

    The pose error is the log map of :math:`\mathbb{R}^3 \times SO(3)` in world axes: the
    twist ``e`` (linear velocity of the frame origin, world angular velocity), applied for
    unit time with the rotation taken about the frame origin, moves ``x`` exactly onto
    ``x*``; feeding ``ẋ = K e`` thus converges for any gain ``K > 0``. (The SE(3) log would
    couple the linear part to the rotation about another point and does not match this
    Jacobian.)

    Continuous joints (``nq = 2``, ``nv = 1``, e.g. Kinova's) are handled with
    ``pin.integrate``/``pin.difference`` around the neutral configuration; their joint
    coordinate is an angle in (−π, π] [rad] and their position limits are ±inf.

    Args:
        name: example-robot-data arm, one of :data:`ARMS` (``panda`` is reduced to 7 DoF with
            both fingers locked at 0; ``z1`` to 6 DoF with the gripper locked).
        urdf: Path of a URDF to load instead of ``name``.
        package_dirs: Directories searched for ``package://`` URIs (kept for peer adapters
            that load meshes; the kinematic model itself needs none).
        frame: End-effector frame; the arm's default (see :data:`ARMS`) when omitted, the
            last frame of the URDF for ``urdf``.
        task: ``"position"`` (n = 3, x shape ``(3,)``) or ``"pose"`` (n = 6, x shape
            ``(4, 4)``).
        position_limits: Override ``[[lower, upper], ...]`` [rad or m], shape ``(nv, 2)``.
        velocity_limits: Override of the joint speed limits [rad/s or m/s], shape ``(nv,)``.
        locked_joints: Extra joints to lock: a list of names (locked at 0, clipped into their
            limits) or a mapping ``name → value`` [rad or m].

    Attributes:
        model: Reduced ``pin.Model``.
        data: Its ``pin.Data`` (reused every step).
        frame_id: Index of the end-effector frame in ``model.frames``.
        frame_name: Its name.
        urdf_path: Absolute URDF path.
        package_dirs: Package directories (list of str).
        reach: Conservative reach bound [m] from the first joint (see :meth:`can_reach`).
        locked_joints: Value [rad or m] each joint removed from the model is fixed at.

    Raises:
        RobotLoadError: Unknown ``name`` (listing valid names), missing URDF (naming the
            path), both or neither of ``name``/``urdf``, or an unsupported joint type.
        FrameNotFound: Unknown ``frame`` (listing the valid frames).
        DimensionError: An override has the wrong shape.
    """

    parameter_constraints: ClassVar[Constraints] = {
        "name": [InstanceOf((str,), f"an example-robot-data arm: {', '.join(sorted(ARMS))}"), None],
        "urdf": [InstanceOf((str, os.PathLike), "a path to a .urdf file"), None],
        "package_dirs": [
            InstanceOf(
                (list, tuple),
                "a list of folders where the URDF package:// meshes are found",
                exclude=(str,),
            ),
            None,
        ],
        "frame": [InstanceOf((str,), "the name of a frame (link) of the URDF"), None],
        "task": OneOf("pose", "position"),
        "position_limits": [
            InstanceOf(
                (list, tuple, np.ndarray),
                "a list of [lower, upper] [rad or m] per joint",
                exclude=(str,),
            ),
            None,
        ],
        "velocity_limits": [
            ArrayOf(
                Interval(Real, 0, None, closed="neither", unit="rad/s", inf_ok=True), per="joint"
            ),
            None,
        ],
        "locked_joints": [
            InstanceOf(
                (list, tuple, Mapping),
                "a list of joint names (locked at neutral) or {joint: value [rad or m]}",
                exclude=(str,),
            ),
            None,
        ],
    }

    def __init__(
        self,
        name: str | None = None,
        urdf: str | None = None,
        package_dirs: Sequence[str] | None = None,
        frame: str | None = None,
        task: TaskKind = "pose",
        position_limits: Sequence[Sequence[float]] | None = None,
        velocity_limits: Sequence[float] | None = None,
        locked_joints: Sequence[str] | Mapping[str, float] | None = None,
    ) -> None:
        if task not in _TASK_DIMS:
            raise ParameterError("task", f"must be 'position' or 'pose', got {task!r}")
        source = _resolve_source(name, urdf, package_dirs)
        self.name = source.name
        self.urdf_path: str | None = source.urdf_path
        self.package_dirs: list[str] = source.package_dirs
        self.task_kind = task
        if urdf is not None:  # a user's package: its meshes stay inside it
            check_meshes(source.urdf_path, source.package_dirs)
        try:
            full = pin.buildModelFromUrdf(source.urdf_path)
        except (RuntimeError, ValueError) as error:
            raise RobotLoadError(f"urdf: cannot parse {source.urdf_path}: {error}") from error
        locked = dict(source.locked)
        if isinstance(locked_joints, Mapping):
            locked.update({str(k): float(v) for k, v in locked_joints.items()})
        elif locked_joints is not None:
            locked.update(dict.fromkeys((str(k) for k in locked_joints), None))
        self.model, self.locked_joints = self._reduce(full, locked)
        if self.model.nv == 0:
            what = "after locking " + ", ".join(locked) if locked else "(every joint is fixed)"
            raise RobotLoadError(
                f"urdf: {source.name} has no movable joint {what}; an arm needs a revolute, "
                "prismatic or continuous joint"
            )
        self.data = self.model.createData()
        self._select_frame(frame if frame is not None else source.frame)
        self._check_joint_types()
        self._names = tuple(str(n) for n in list(self.model.names)[1:])
        self._nq, self._nv = int(self.model.nq), int(self.model.nv)
        self._neutral = pin.neutral(self.model)
        self._lower, self._upper = self._position_limits(position_limits)
        self._velocity = self._velocity_limits(velocity_limits)
        self._euclidean = self.model.nq == self.model.nv
        self._rows = _TASK_DIMS[task]
        self.reach = self._reach_bound()

    # ------------------------------------------------------------------ loading
    @staticmethod
    def _reduce(full: Any, locked: Mapping[str, float | None]) -> tuple[Any, dict[str, float]]:
        """Model with the ``locked`` joints fixed (value None: 0 clipped into its limits).

        Returns:
            The reduced model and the value [rad or m] each locked joint is fixed at.
        """
        if not locked:
            return full, {}
        joint_ids = []
        values: dict[str, float] = {}
        reference = pin.neutral(full)
        valid = [str(n) for n in list(full.names)[1:]]
        for joint, value in locked.items():
            if joint not in valid:
                raise RobotLoadError(
                    f"locked_joints: unknown joint {joint!r}; valid joints: {', '.join(valid)}"
                )
            jid = full.getJointId(joint)
            joint_model = full.joints[jid]
            if joint_model.nq != 1:
                raise RobotLoadError(
                    f"locked_joints: joint {joint!r} has nq={joint_model.nq}; only 1-DoF "
                    "revolute or prismatic joints can be locked"
                )
            iq = joint_model.idx_q
            lo, hi = full.lowerPositionLimit[iq], full.upperPositionLimit[iq]
            reference[iq] = min(max(0.0 if value is None else value, lo), hi)
            values[joint] = float(reference[iq])
            joint_ids.append(jid)
        return pin.buildReducedModel(full, joint_ids, reference), values

    def _select_frame(self, frame_name: str | None) -> None:
        """Set the end-effector frame (the model's last frame when None).

        Raises:
            FrameNotFound: ``frame_name`` is not a frame of the model.
        """
        if frame_name is None:
            frame_name = str(self.model.frames[len(self.model.frames) - 1].name)
        names = [str(f.name) for f in self.model.frames]
        if frame_name not in names:
            raise FrameNotFound(frame_name, sorted(set(names)))
        self.frame_name = frame_name
        self.frame_id = self._frame_index(frame_name)

    def _position_limits(
        self, override: Sequence[Sequence[float]] | None
    ) -> tuple[FloatArray, FloatArray]:
        """``(lower, upper)`` [rad or m], shapes ``(nv,)``: the override or the URDF's."""
        if override is None:
            return self._default_position_limits()
        bounds = np.asarray(override, dtype=float)
        if bounds.shape != (self.nv, 2):
            raise DimensionError("position_limits", (self.nv, 2), bounds.shape)
        if np.any(bounds[:, 0] >= bounds[:, 1]):
            raise ParameterError(
                "position_limits", "each row must be [lower, upper] with lower < upper"
            )
        return bounds[:, 0].copy(), bounds[:, 1].copy()

    def _velocity_limits(self, override: Sequence[float] | None) -> FloatArray:
        """Joint speed limits [rad/s or m/s], shape ``(nv,)``: the override or the URDF's."""
        if override is None:
            speeds = np.array(self.model.velocityLimit, dtype=float)
            speeds[~(speeds > 0.0)] = np.inf  # URDFs without a limit give 0
            return speeds
        speeds = np.asarray(override, dtype=float)
        if speeds.shape != (self.nv,):
            raise DimensionError("velocity_limits", (self.nv,), speeds.shape)
        if np.any(~(speeds > 0.0)):
            raise ParameterError("velocity_limits", "every limit must be > 0 [rad/s or m/s]")
        return speeds

    def _frame_index(self, frame_name: str) -> int:
        """Index of ``frame_name``; a body frame wins when a joint frame shares its name."""
        matches = [i for i, f in enumerate(self.model.frames) if f.name == frame_name]
        bodies = [i for i in matches if self.model.frames[i].type == pin.FrameType.BODY]
        return int((bodies or matches)[0])

    def _check_joint_types(self) -> None:
        for jid in range(1, self.model.njoints):
            joint = self.model.joints[jid]
            if not ((joint.nq == 1 and joint.nv == 1) or (joint.nq == 2 and joint.nv == 1)):
                raise RobotLoadError(
                    f"urdf: joint {self.model.names[jid]!r} ({joint.shortname()}) is not "
                    "supported; allowed: revolute, prismatic, continuous"
                )

    def _default_position_limits(self) -> tuple[FloatArray, FloatArray]:
        """The URDF's limits; refused when one is reversed or none leaves room to move.

        Raises:
            RobotLoadError: A joint with ``lower > upper``, or every joint with
                ``lower == upper`` (no target but the start's own pose is reachable).
        """
        lower = np.full(self.model.nv, -np.inf)
        upper = np.full(self.model.nv, np.inf)
        for jid in range(1, self.model.njoints):
            joint = self.model.joints[jid]
            if joint.nq == 1:  # revolute / prismatic; continuous joints stay unbounded
                lower[joint.idx_v] = self.model.lowerPositionLimit[joint.idx_q]
                upper[joint.idx_v] = self.model.upperPositionLimit[joint.idx_q]
                if lower[joint.idx_v] > upper[joint.idx_v]:
                    raise RobotLoadError(
                        f"urdf: joint {self.model.names[jid]!r} has lower limit "
                        f"{lower[joint.idx_v]:g} > upper {upper[joint.idx_v]:g}"
                    )
        if lower.size and np.all(upper - lower <= 0.0):
            raise RobotLoadError(
                "urdf: every joint's position limits are lower == upper: the arm cannot move, "
                "so every target but its start pose is unreachable"
            )
        return lower, upper

    def _reach_bound(self) -> float:
        r"""Conservative reach [m]: sum of the link offsets from the first joint.

        .. math:: r = \sum_{i} \|p_{i+1} - p_i\| + \|p_f - p_{last}\| + \sum_{prismatic}
                  \max(|q_{lo}|, |q_{hi}|)

        over the joints supporting the frame. Each offset between successive revolute joint
        origins is invariant under joint motion, so by the triangle inequality
        ``‖p_f − p_1‖ ≤ r`` in every configuration.
        """
        data = self.model.createData()
        pin.forwardKinematics(self.model, data, self._neutral)
        pin.updateFramePlacement(self.model, data, self.frame_id)
        parent = self.model.frames[self.frame_id].parentJoint
        chain = [j for j in self.model.supports[parent] if j > 0]
        if not chain:
            self._base = np.asarray(data.oMf[self.frame_id].translation).copy()
            return 0.0
        points = [np.asarray(data.oMi[j].translation) for j in chain]
        points.append(np.asarray(data.oMf[self.frame_id].translation))
        reach = sum(float(np.linalg.norm(b - a)) for a, b in zip(points, points[1:], strict=False))
        for j in chain:
            joint = self.model.joints[j]
            if joint.shortname().startswith("JointModelP"):  # prismatic travel
                lo = self.model.lowerPositionLimit[joint.idx_q]
                hi = self.model.upperPositionLimit[joint.idx_q]
                reach += float(max(abs(lo), abs(hi)))
        self._base = points[0].copy()
        return float(reach)

    # ---------------------------------------------------------------- interface
    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of the ``nv`` (unlocked) joints."""
        return self._names

    @property
    def nv(self) -> int:
        """Number of joint velocity coordinates."""
        return self._nv

    @property
    def nq(self) -> int:
        """Size of the configuration vector (> nv with continuous joints)."""
        return self._nq

    @property
    def task_dim(self) -> int:
        """3 for a position task, 6 for a pose task."""
        return self._rows

    @property
    def position_limits(self) -> tuple[FloatArray, FloatArray]:
        """Joint position limits [rad or m], shapes ``(nv,)``; ±inf for continuous joints."""
        return self._lower, self._upper

    @property
    def velocity_limits(self) -> FloatArray:
        """Joint speed limits [rad/s or m/s], shape ``(nv,)``."""
        return self._velocity

    def kinematics(self, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Frame position ``(3,)`` or pose ``(4, 4)``, and the ``LOCAL_WORLD_ALIGNED`` Jacobian.

        Args:
            q: Configuration, shape ``(nq,)``.

        Returns:
            ``(x, J)`` with ``J`` of shape ``(3, nv)`` (linear rows) or ``(6, nv)``.
        """
        model, data = self.model, self.data
        pin.forwardKinematics(model, data, q)
        placement = pin.updateFramePlacement(model, data, self.frame_id)
        jacobian = pin.computeFrameJacobian(model, data, q, self.frame_id, pin.LOCAL_WORLD_ALIGNED)
        if self._rows == 3:
            return placement.translation.copy(), jacobian[:3].copy()
        return placement.homogeneous, jacobian

    def jacobian_derivative(self, q: FloatArray, direction: FloatArray) -> FloatArray:
        r"""Time variation of the ``LOCAL_WORLD_ALIGNED`` frame Jacobian for ``q̇ = direction``.

        Pinocchio's ``computeJointJacobiansTimeVariation`` + ``getFrameJacobianTimeVariation``
        (exact, one pass), shape ``(3, nv)`` or ``(6, nv)``.
        """
        model, data = self.model, self.data
        pin.computeJointJacobiansTimeVariation(model, data, q, np.asarray(direction, dtype=float))
        pin.updateFramePlacements(model, data)
        rate = pin.getFrameJacobianTimeVariation(
            model, data, self.frame_id, pin.LOCAL_WORLD_ALIGNED
        )
        return np.asarray(rate[: self._rows], dtype=float)

    def task_error(self, x_target: FloatArray, x: FloatArray) -> FloatArray:
        r"""Error driving ``x`` to ``x_target``, world axes.

        .. math:: e = (p^* - p,\ \log_{SO(3)}(R^* R^\top))

        Returns:
            Shape ``(3,)`` [m] (position task) or ``(6,)`` [m, rad] (pose task).
        """
        if self._rows == 3:
            return np.asarray(x_target, dtype=float) - np.asarray(x, dtype=float)
        target = np.asarray(x_target, dtype=float)
        current = np.asarray(x, dtype=float)
        error = np.empty(6)
        error[:3] = target[:3, 3] - current[:3, 3]
        error[3:] = pin.log3(target[:3, :3] @ current[:3, :3].T)
        return error

    def integrate(self, q: FloatArray, v: FloatArray, dt: float) -> FloatArray:
        """``q ⊕ v·dt`` on the configuration manifold (``pin.integrate``), ``dt`` in [s]."""
        if self._euclidean:
            return q + v * dt
        return np.asarray(pin.integrate(self.model, q, v * dt))

    def configuration(self, joint_coordinates: FloatArray) -> FloatArray:
        """Configuration ``q`` (nq,) from joint coordinates (nv,): ``neutral ⊕ θ``."""
        theta = np.asarray(joint_coordinates, dtype=float)
        if theta.shape != (self.nv,):
            raise DimensionError("joint_coordinates", (self.nv,), theta.shape)
        if self._euclidean:
            return theta.copy()
        return np.asarray(pin.integrate(self.model, self._neutral, theta))

    def joint_coordinates(self, q: FloatArray) -> FloatArray:
        """Joint coordinates (nv,) of ``q`` (nq,): ``q ⊖ neutral``; continuous in (−π, π]."""
        if self._euclidean:
            return np.array(q, dtype=float)
        return np.asarray(pin.difference(self.model, self._neutral, q))

    def peer_description(self) -> PeerDescription:
        """The arm's URDF, frame and package directories, with its own reduced model.

        The reduced ``pin.Model`` (locked joints at their lock values) and frame index are
        handed over as is, so pink runs on the very model our backends use; mesh paths
        relative to the URDF file are made absolute (the text no longer has a directory).

        Raises:
            RobotLoadError: The URDF file cannot be read.
        """
        path = str(self.urdf_path)
        try:
            root = ET.parse(path).getroot()
        except (OSError, ET.ParseError) as error:
            raise RobotLoadError(f"urdf: cannot read {path}: {error}") from error
        directory = os.path.dirname(path)
        for mesh in root.iter("mesh"):
            filename = mesh.get("filename", "")
            if filename and "://" not in filename and not os.path.isabs(filename):
                mesh.set("filename", os.path.normpath(os.path.join(directory, filename)))
        return PeerDescription(
            urdf=ET.tostring(root, encoding="unicode"),
            frame=self.frame_name,
            joint_names=self.joint_names,
            package_dirs=tuple(self.package_dirs),
            pinocchio_model=self.model,
            frame_id=self.frame_id,
        )

    def can_reach(self, x: FloatArray) -> bool:
        """Whether the target position is within :attr:`reach` [m] of the first joint.

        A necessary condition only (conservative: the bound ignores joint limits).
        """
        target = np.asarray(x, dtype=float)
        position = target[:3, 3] if target.ndim == 2 else target[:3]
        return float(np.linalg.norm(position - self._base)) <= self.reach + 1e-9
