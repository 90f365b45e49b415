r"""One robot, three modelling libraries: each peer's model built from a robot's description.

A peer must control *the same* arm as our own backends. It never looks at the robot's class:
it asks the robot for a :class:`~otmm_qp.robots.peer_description.PeerDescription`
(:meth:`Robot.peer_description <otmm_qp.robots.robot.Robot.peer_description>`, once, at
bind time; :func:`describe` checks it against the robot) and builds from it:

* Pinocchio (pink; frame placement for mink and Drake): the description's own
  ``pinocchio_model`` when given (a :class:`~otmm_qp.robots.pinocchio_arm.PinocchioArm`'s
  reduced model), else a model parsed from :func:`peer_urdf` — see
  :class:`PinocchioPeerModel` for how our coordinates map into it;
* MuJoCo (mink): the description's ``mjcf`` when given (planar arms), else :func:`peer_urdf`
  with a site :data:`MUJOCO_SITE` at the end-effector frame (:func:`mujoco_model`);
* Drake: :func:`peer_urdf` without geometry.

:func:`peer_urdf` rewrites the description's URDF for another library: ``package://`` URIs
resolved against its ``package_dirs``, movable joints that are not the robot's turned
``fixed`` (at 0), meshes a library cannot read dropped.

Joint ordering differs between libraries, so every peer maps by joint name (:class:`JointMap`,
:class:`PinocchioPeerModel`).
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from otmm_qp.exceptions import FrameNotFound, RobotLoadError
from otmm_qp.robots.peer_description import PeerDescription
from otmm_qp.robots.planar_arm import PLANAR_FRAME, planar_mjcf, planar_urdf
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.robots.velocity_task import task_rows

__all__ = [
    "MUJOCO_MESH_FORMATS",
    "MUJOCO_SITE",
    "PLANAR_FRAME",
    "JointMap",
    "PinocchioPeerModel",
    "describe",
    "model_mismatch",
    "mujoco_joint_map",
    "mujoco_model",
    "mujoco_site_pose",
    "mujoco_spec",
    "peer_urdf",
    "pinocchio_frame_pose",
    "pinocchio_model",
    "planar_mjcf",
    "planar_urdf",
    "pose_mismatch",
    "resolve_package_uri",
    "root_link",
]

#: Name of the MuJoCo site added at the end-effector frame of a URDF arm.
MUJOCO_SITE = "otmm_ee"
#: Mesh formats MuJoCo loads; geometry in other formats (e.g. ``.dae``) is dropped.
MUJOCO_MESH_FORMATS = (".stl", ".obj", ".msh")


def describe(robot: Robot) -> PeerDescription:
    """The robot's :class:`PeerDescription`, checked against the robot.

    Raises:
        RobotLoadError: The robot does not implement ``peer_description`` (the base class's
            one-line message), its joint names differ from ``robot.joint_names``, or the
            task the description implies (planar xy, position, pose) does not have
            ``robot.task_dim`` rows.
    """
    description = robot.peer_description()
    if description.joint_names != tuple(robot.joint_names):
        raise RobotLoadError(
            f"robot {robot.name!r}: peer_description().joint_names "
            f"{list(description.joint_names)} differ from robot.joint_names "
            f"{list(robot.joint_names)}"
        )
    rows = task_rows(description.planar, robot.task_kind)
    if rows.size != robot.task_dim:
        raise RobotLoadError(
            f"robot {robot.name!r}: a peer commands {rows.size} task rows (planar="
            f"{description.planar}, task_kind={robot.task_kind!r}) but task_dim is "
            f"{robot.task_dim}"
        )
    return description


def _description(source: Robot | PeerDescription) -> PeerDescription:
    """``source`` itself, or the checked description of a robot (:func:`describe`)."""
    return source if isinstance(source, PeerDescription) else describe(source)


def resolve_package_uri(uri: str, package_dirs: Sequence[str]) -> str:
    """Absolute path of a ``package://PKG/rel`` URI: the first ``DIR/PKG/rel`` that exists.

    Args:
        uri: Mesh URI; a plain path is returned unchanged.
        package_dirs: Directories holding packages (``robot.package_dirs``).

    Raises:
        RobotLoadError: No package directory holds the file (naming the URI and the
            directories searched).
    """
    if not uri.startswith("package://"):
        return uri
    relative = uri.removeprefix("package://")
    for directory in package_dirs:
        candidate = os.path.normpath(os.path.join(directory, relative))
        if os.path.exists(candidate):
            return candidate
    raise RobotLoadError(
        f"urdf: cannot resolve {uri!r}; searched {', '.join(package_dirs) or '(no package_dirs)'}"
    )


def peer_urdf(
    source: Robot | PeerDescription, keep_geometry: bool = True, mesh_formats: Sequence[str] = ()
) -> str:
    """The description's URDF rewritten for another library.

    * ``package://`` mesh URIs become absolute paths (:func:`resolve_package_uri`);
    * movable joints absent from ``joint_names`` (locked by the robot, e.g. Panda's fingers)
      become ``fixed`` — at 0, so a joint locked elsewhere shows up as a pose mismatch in
      :func:`pose_mismatch`;
    * with ``keep_geometry=False`` every ``<visual>``/``<collision>`` is dropped (kinematics
      only); with ``mesh_formats`` given, meshes in other formats are dropped.

    Args:
        source: A robot (asked for its description) or a description.
        keep_geometry: Keep visual and collision elements.
        mesh_formats: Lower-case file suffixes to keep (all when empty).

    Raises:
        RobotLoadError: The URDF is not valid XML, or a mesh URI cannot be resolved.
    """
    description = _description(source)
    try:
        root = ET.fromstring(description.urdf)
    except ET.ParseError as error:
        raise RobotLoadError(f"urdf: the peer description's URDF is not XML: {error}") from error
    keep = set(description.joint_names)
    for joint in root.iter("joint"):
        if joint.get("type") != "fixed" and joint.get("name") not in keep:
            joint.set("type", "fixed")
    for link in root.iter("link"):
        for tag in ("visual", "collision"):
            for element in list(link.findall(tag)):
                mesh = element.find("geometry/mesh")
                drop = not keep_geometry
                if mesh is not None and not drop:
                    filename = resolve_package_uri(
                        mesh.get("filename", ""), description.package_dirs
                    )
                    mesh.set("filename", filename)
                    drop = bool(mesh_formats) and not filename.lower().endswith(tuple(mesh_formats))
                if drop:
                    link.remove(element)
    return ET.tostring(root, encoding="unicode")


def root_link(urdf: str) -> str:
    """Name of the URDF link that is nobody's child (the base)."""
    root = ET.fromstring(urdf)
    children = {c.get("link") for c in root.iter("child")}
    links = [str(link.get("name")) for link in root.iter("link")]
    return next(name for name in links if name not in children)


@dataclass(frozen=True)
class JointMap:
    r"""Index map between our joint coordinates ``θ`` (nv,) and a peer's vectors.

    .. math:: q_{peer}[\text{index}_i] = \theta_i,\qquad \dot\theta_i = v_{peer}[\text{index}_i]

    Attributes:
        position_index: Index of each of our joints in the peer's position vector, ``(nv,)``.
        velocity_index: Index in the peer's velocity vector, ``(nv,)``.
        nq: Size of the peer's position vector.
    """

    position_index: np.ndarray
    velocity_index: np.ndarray
    nq: int

    def to_peer(self, theta: FloatArray, base: FloatArray | None = None) -> FloatArray:
        """Peer position vector with our joint coordinates ``θ`` [rad or m] written in."""
        q = np.zeros(self.nq) if base is None else np.array(base, dtype=float)
        q[self.position_index] = theta
        return q

    def from_peer_velocity(self, v: FloatArray) -> FloatArray:
        """Our joint velocity (nv,) [rad/s] from the peer's velocity vector."""
        return np.asarray(v, dtype=float)[self.velocity_index]


def pinocchio_model(source: Robot | PeerDescription) -> tuple[Any, int]:
    """Pinocchio model of the described arm and the index of its end-effector frame.

    The description's ``pinocchio_model`` and ``frame_id`` when given (for a
    :class:`~otmm_qp.robots.pinocchio_arm.PinocchioArm`, the very model our backends use);
    otherwise a model parsed from :func:`peer_urdf` (kinematics only), the frame looked up
    by name (a body frame wins over a joint frame of the same name).

    Raises:
        RobotLoadError: Pinocchio cannot parse the URDF.
        FrameNotFound: The description's ``frame`` is not a frame of the model.
    """
    description = _description(source)
    if description.pinocchio_model is not None and description.frame_id is not None:
        return description.pinocchio_model, int(description.frame_id)
    try:
        model = pin.buildModelFromXML(peer_urdf(description, keep_geometry=False))
    except (RuntimeError, ValueError) as error:
        raise RobotLoadError(f"urdf: Pinocchio cannot parse the peer URDF: {error}") from error
    matches = [i for i, f in enumerate(model.frames) if f.name == description.frame]
    if not matches:
        raise FrameNotFound(description.frame, {str(f.name) for f in model.frames})
    bodies = [i for i in matches if model.frames[i].type == pin.FrameType.BODY]
    return model, int((bodies or matches)[0])


@dataclass(frozen=True)
class PinocchioPeerModel:
    r"""A Pinocchio model of the robot for a peer, and our coordinates in it.

    .. math::
        q_{pin} = \begin{cases} q & \text{own model} \\
        \theta & \text{Euclidean, same joint order} \\
        \text{integrate}(q_{neutral},\ v),\ v[\text{velocity\_index}] = \theta
        & \text{otherwise} \end{cases}
        \qquad \dot\theta = v_{pin}[\text{velocity\_index}]

    with ``θ = robot.joint_coordinates(q)`` (nv,). Build with :meth:`create`, once per bind.

    Attributes:
        model: The ``pin.Model``.
        frame_id: End-effector frame index in ``model.frames``.
        velocity_index: Index of each of our joints in the model's velocity vector, ``(nv,)``.
        own: The description's own model: its configuration is the robot's ``q`` (nq,).
        same_order: ``velocity_index`` is ``0 … nv−1`` (no reordering needed).
        euclidean: ``model.nq == model.nv`` (no continuous joints).
        neutral: ``pin.neutral(model)``, shape ``(model.nq,)``.
    """

    model: Any
    frame_id: int
    velocity_index: np.ndarray
    own: bool
    same_order: bool
    euclidean: bool
    neutral: FloatArray

    @classmethod
    def create(cls, description: PeerDescription, robot: Robot) -> PinocchioPeerModel:
        """The model of :func:`pinocchio_model` with the index map of ``robot``'s joints.

        Raises:
            RobotLoadError: A joint of the robot is not a movable joint of the model, the
                model has other movable joints, or a given ``pinocchio_model`` does not
                have the robot's joints in order and the robot's ``nq``.
        """
        model, frame_id = pinocchio_model(description)
        own = description.pinocchio_model is not None
        names = [str(n) for n in list(model.names)[1:]]
        if own and (names != list(robot.joint_names) or int(model.nq) != robot.nq):
            raise RobotLoadError(
                f"robot {robot.name!r}: PeerDescription.pinocchio_model must have the joints "
                f"{list(robot.joint_names)} in order and nq={robot.nq}; it has {names}, "
                f"nq={int(model.nq)}"
            )
        missing = [n for n in robot.joint_names if n not in names]
        if missing or len(names) != robot.nv or int(model.nv) != robot.nv:
            raise RobotLoadError(
                f"robot {robot.name!r}: the peer URDF's movable joints {names} are not the "
                f"robot's joints {list(robot.joint_names)} (one velocity coordinate each)"
            )
        index = np.array([model.joints[model.getJointId(n)].idx_v for n in robot.joint_names])
        return cls(
            model=model,
            frame_id=frame_id,
            velocity_index=index,
            own=own,
            same_order=bool(np.array_equal(index, np.arange(robot.nv))),
            euclidean=int(model.nq) == int(model.nv),
            neutral=np.asarray(pin.neutral(model)),
        )

    def configuration(self, robot: Robot, q: FloatArray) -> FloatArray:
        """The model's configuration (model.nq,) at the robot's configuration ``q`` (nq,)."""
        if self.own:
            return q
        theta = robot.joint_coordinates(q)
        if self.same_order:
            if self.euclidean:
                return theta
            return np.asarray(pin.integrate(self.model, self.neutral, theta))
        v = np.zeros(self.model.nv)
        v[self.velocity_index] = theta
        if self.euclidean:
            return v
        return np.asarray(pin.integrate(self.model, self.neutral, v))

    def velocity(self, v: FloatArray) -> FloatArray:
        """Our joint velocity (nv,) [rad/s or m/s] from the model's velocity vector."""
        if self.same_order:
            return np.asarray(v, dtype=float)
        return np.asarray(v, dtype=float)[self.velocity_index]


def mujoco_model(
    source: Robot | PeerDescription, pinocchio: tuple[Any, int] | None = None
) -> tuple[Any, str]:
    """MuJoCo model of the described arm and the name of its end-effector site.

    The compiled :func:`mujoco_spec`.

    Args:
        source: A robot (asked for its description) or a description.
        pinocchio: ``(model, frame_id)`` of :func:`pinocchio_model`, when already built.

    Raises:
        RobotLoadError: MuJoCo rejects the MJCF/URDF, or the MJCF has no site ``frame``.
    """
    spec, site = mujoco_spec(source, pinocchio)
    try:
        return spec.compile(), site
    except ValueError as error:
        raise RobotLoadError(f"MuJoCo cannot compile the peer model: {error}") from error


def mujoco_spec(
    source: Robot | PeerDescription, pinocchio: tuple[Any, int] | None = None
) -> tuple[Any, str]:
    """MuJoCo ``MjSpec`` of the described arm (to add to before compiling) and its site name.

    The description's ``mjcf`` when given (its site ``frame``); otherwise its URDF through
    :func:`peer_urdf` (absolute mesh paths, ``strippath="false"`` so MuJoCo keeps them,
    ``fusestatic="false"``) with a site :data:`MUJOCO_SITE` on the body of the frame's
    parent joint, placed at the frame's Pinocchio placement in that joint frame.

    Args:
        source: A robot (asked for its description) or a description.
        pinocchio: ``(model, frame_id)`` of :func:`pinocchio_model`, when already built.

    Raises:
        RobotLoadError: MuJoCo rejects the MJCF/URDF, or the MJCF has no site ``frame``.
    """
    import mujoco

    description = _description(source)
    if description.mjcf is not None:
        try:
            spec = mujoco.MjSpec.from_string(description.mjcf)
            compiled = spec.compile()
        except ValueError as error:
            raise RobotLoadError(f"mjcf: MuJoCo cannot load the peer MJCF: {error}") from error
        if mujoco.mj_name2id(compiled, mujoco.mjtObj.mjOBJ_SITE, description.frame) < 0:
            raise RobotLoadError(f"mjcf: no site named {description.frame!r}")
        return spec, description.frame
    model, frame_id = pinocchio if pinocchio is not None else pinocchio_model(description)
    text = peer_urdf(description, mesh_formats=MUJOCO_MESH_FORMATS)
    root = ET.fromstring(text)
    extension = ET.SubElement(root, "mujoco")
    ET.SubElement(
        extension, "compiler", strippath="false", fusestatic="false", discardvisual="true"
    )
    try:
        spec = mujoco.MjSpec.from_string(ET.tostring(root, encoding="unicode"))
    except ValueError as error:
        raise RobotLoadError(f"urdf: MuJoCo cannot load {root.get('name')!r}: {error}") from error
    frame = model.frames[frame_id]
    joint_name = str(model.names[frame.parentJoint])
    body = next((j.parent for j in spec.joints if j.name == joint_name), None)
    if body is None:
        raise RobotLoadError(f"urdf: joint {joint_name!r} is not in the MuJoCo model")
    quaternion = pin.Quaternion(frame.placement.rotation)  # (x, y, z, w) storage
    body.add_site(
        name=MUJOCO_SITE,
        pos=np.asarray(frame.placement.translation),
        quat=[quaternion.w, quaternion.x, quaternion.y, quaternion.z],
    )
    return spec, MUJOCO_SITE


def mujoco_joint_map(robot: Robot, model: Any) -> JointMap:
    """Map our joints to MuJoCo ``qpos`` / ``qvel`` addresses by joint name.

    Raises:
        RobotLoadError: A joint of ``robot`` is missing from the MuJoCo model.
    """
    import mujoco

    positions, velocities = [], []
    for name in robot.joint_names:
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid < 0:
            raise RobotLoadError(f"joint {name!r} is not in the MuJoCo model")
        positions.append(int(model.jnt_qposadr[jid]))
        velocities.append(int(model.jnt_dofadr[jid]))
    return JointMap(np.array(positions), np.array(velocities), int(model.nq))


def mujoco_site_pose(model: Any, data: Any, site: str, qpos: FloatArray) -> FloatArray:
    """World pose ``T`` (4, 4) of ``site`` at ``qpos`` (MuJoCo forward kinematics)."""
    import mujoco

    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
    pose = np.eye(4)
    pose[:3, :3] = np.asarray(data.site_xmat[sid]).reshape(3, 3)
    pose[:3, 3] = data.site_xpos[sid]
    return pose


def pinocchio_frame_pose(model: Any, frame_id: int, q: FloatArray) -> FloatArray:
    """World pose ``T`` (4, 4) of frame ``frame_id`` at Pinocchio configuration ``q`` (nq,)."""
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return np.asarray(data.oMf[frame_id].homogeneous)


def model_mismatch(
    robot: Robot,
    pinocchio: PinocchioPeerModel,
    mujoco_pair: tuple[Any, str],
    theta: FloatArray,
) -> tuple[float, float]:
    r"""How far a Pinocchio and a MuJoCo model disagree on the end-effector pose at ``θ``.

    .. math:: e_p = \|p_{pin} - p_{mj}\|,\qquad e_R = \|\log(R_{pin}^\top R_{mj})\|

    Args:
        robot: The robot both models describe.
        pinocchio: Its Pinocchio model (:class:`PinocchioPeerModel`).
        mujoco_pair: ``(MjModel, site)`` of :func:`mujoco_model`.
        theta: Joint coordinates [rad or m], shape ``(nv,)``.

    Returns:
        ``(e_p [m], e_R [rad])``.
    """
    import mujoco

    theta = np.asarray(theta, dtype=float)
    q = pinocchio.configuration(robot, robot.configuration(theta))
    pose_pin = pinocchio_frame_pose(pinocchio.model, pinocchio.frame_id, q)
    mj_model, site = mujoco_pair
    qpos = mujoco_joint_map(robot, mj_model).to_peer(theta, mj_model.qpos0)
    pose_mj = mujoco_site_pose(mj_model, mujoco.MjData(mj_model), site, qpos)
    e_p = float(np.linalg.norm(pose_pin[:3, 3] - pose_mj[:3, 3]))
    e_r = float(np.linalg.norm(pin.log3(pose_pin[:3, :3].T @ pose_mj[:3, :3])))
    return e_p, e_r


def pose_mismatch(robot: Robot, theta: FloatArray) -> tuple[float, float]:
    """:func:`model_mismatch` of the Pinocchio and MuJoCo models built from the robot.

    Args:
        robot: Any robot implementing ``peer_description``.
        theta: Joint coordinates [rad or m], shape ``(nv,)``.

    Returns:
        ``(e_p [m], e_R [rad])``.
    """
    description = describe(robot)
    pinocchio = PinocchioPeerModel.create(description, robot)
    pair = mujoco_model(description, (pinocchio.model, pinocchio.frame_id))
    return model_mismatch(robot, pinocchio, pair, theta)
