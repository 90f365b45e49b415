r"""One robot, three modelling libraries: URDF/MJCF generation and URDF rewriting for peers.

A peer must control *the same* arm as our own backends. This module builds each peer's
model from the robot the experiment already loaded:

* :class:`~otmm_qp.robots.planar_arm.PlanarArm` → a generated URDF (Pinocchio for pink,
  Drake) or MJCF (MuJoCo for mink). Joint ``i`` rotates about the world ``z`` axis, link ``i``
  runs along the local ``x`` axis with length ``l_i`` [m], and the end-effector frame ``ee``
  sits at the tip, so the frame's ``(x, y)`` equals :meth:`PlanarArm.forward`.
* :class:`~otmm_qp.robots.pinocchio_arm.PinocchioArm` → its own reduced ``pin.Model`` (pink),
  or its URDF rewritten (Drake, MuJoCo): ``package://`` URIs resolved against
  ``robot.package_dirs``, joints that the reduced model locked turned ``fixed`` (at 0),
  meshes MuJoCo cannot read dropped.

Joint ordering differs between libraries, so every peer maps by joint name through
:class:`JointMap`.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from otmm_qp.exceptions import RobotLoadError
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.robots.robot import FloatArray, Robot

#: Name of the end-effector frame (URDF link) / site (MJCF) of generated planar models.
PLANAR_FRAME = "ee"
#: Name of the MuJoCo site added at the end-effector frame of a URDF arm.
MUJOCO_SITE = "otmm_ee"
#: Mesh formats MuJoCo loads; geometry in other formats (e.g. ``.dae``) is dropped.
MUJOCO_MESH_FORMATS = (".stl", ".obj", ".msh")


def _fmt(value: float) -> str:
    return f"{value:.17g}"


def planar_urdf(arm: PlanarArm) -> str:
    r"""URDF text of a planar arm, base fixed at the world origin.

    Joint ``i`` sits at the tip of link ``i−1`` (``origin xyz = (l_{i-1}, 0, 0)``) and turns
    about ``z``; finite limits give ``revolute`` joints, unbounded ones ``continuous``.
    Links get a unit point mass (Drake rejects massless bodies in some checks).

    Args:
        arm: The planar arm; lengths [m], limits [rad], speed limits [rad/s].

    Returns:
        URDF XML; the end-effector link is ``ee`` (:data:`PLANAR_FRAME`).
    """
    lower, upper = arm.position_limits
    speeds = arm.velocity_limits
    inertial = (
        '<inertial><mass value="1"/><origin xyz="0 0 0"/>'
        '<inertia ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/></inertial>'
    )
    lines = [f'<robot name="{arm.name}">', f'  <link name="base">{inertial}</link>']
    parent, offset = "base", 0.0
    for i, name in enumerate(arm.joint_names):
        bounded = bool(np.isfinite(lower[i]) and np.isfinite(upper[i]))
        speed = _fmt(float(speeds[i])) if np.isfinite(speeds[i]) else "0"
        limit = (
            f'<limit lower="{_fmt(lower[i])}" upper="{_fmt(upper[i])}" effort="0" '
            f'velocity="{speed}"/>'
            if bounded
            else f'<limit effort="0" velocity="{speed}"/>'
        )
        child = f"link{i + 1}"
        lines += [
            f'  <link name="{child}">{inertial}</link>',
            f'  <joint name="{name}" type="{"revolute" if bounded else "continuous"}">',
            f'    <parent link="{parent}"/><child link="{child}"/>',
            f'    <origin xyz="{_fmt(offset)} 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/>',
            f"    {limit}",
            "  </joint>",
        ]
        parent, offset = child, float(arm.link_lengths[i])
    lines += [
        f'  <link name="{PLANAR_FRAME}">{inertial}</link>',
        f'  <joint name="{PLANAR_FRAME}_joint" type="fixed">',
        f'    <parent link="{parent}"/><child link="{PLANAR_FRAME}"/>',
        f'    <origin xyz="{_fmt(offset)} 0 0" rpy="0 0 0"/>',
        "  </joint>",
        "</robot>",
    ]
    return "\n".join(lines) + "\n"


def planar_mjcf(arm: PlanarArm) -> str:
    r"""MJCF text of a planar arm, in radians.

    MJCF reads angles in *degrees* unless ``<compiler angle="radian"/>``; the joint ranges
    here are radians, so the compiler flag is set. Hinges turn about ``z``; unbounded joints
    are ``limited="false"``. The end-effector site is ``ee`` (:data:`PLANAR_FRAME`).

    Args:
        arm: The planar arm; lengths [m], limits [rad].

    Returns:
        MJCF XML.
    """
    lower, upper = arm.position_limits
    lines = [
        f'<mujoco model="{arm.name}">',
        '  <compiler angle="radian" autolimits="true"/>',
        '  <option integrator="Euler" gravity="0 0 0"/>',
        "  <worldbody>",
    ]
    offset, depth = 0.0, 2
    for i, name in enumerate(arm.joint_names):
        pad = "  " * depth
        bounded = bool(np.isfinite(lower[i]) and np.isfinite(upper[i]))
        limit = (
            f'limited="true" range="{_fmt(lower[i])} {_fmt(upper[i])}"'
            if bounded
            else 'limited="false"'
        )
        length = float(arm.link_lengths[i])
        lines += [
            f'{pad}<body name="link{i + 1}" pos="{_fmt(offset)} 0 0">',
            f'{pad}  <joint name="{name}" type="hinge" axis="0 0 1" {limit}/>',
            f'{pad}  <geom type="capsule" fromto="0 0 0 {_fmt(length)} 0 0" size="0.02" mass="1"/>',
        ]
        offset, depth = length, depth + 1
    lines.append(f'{"  " * depth}<site name="{PLANAR_FRAME}" pos="{_fmt(offset)} 0 0"/>')
    for level in range(depth - 1, 1, -1):
        lines.append(f"{'  ' * level}</body>")
    lines += ["  </worldbody>", "</mujoco>"]
    return "\n".join(lines) + "\n"


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


def peer_urdf(robot: Any, keep_geometry: bool = True, mesh_formats: Sequence[str] = ()) -> str:
    """URDF of a :class:`PinocchioArm` rewritten for another library.

    * ``package://`` mesh URIs become absolute paths (:func:`resolve_package_uri`);
    * movable joints absent from ``robot.joint_names`` (locked by the reduced model, e.g.
      Panda's fingers) become ``fixed`` — at 0, so a joint locked elsewhere shows up as a
      pose mismatch in :func:`pose_mismatch`;
    * with ``keep_geometry=False`` every ``<visual>``/``<collision>`` is dropped (kinematics
      only); with ``mesh_formats`` given, meshes in other formats are dropped.

    Args:
        robot: A robot with ``urdf_path``, ``package_dirs`` and ``joint_names``.
        keep_geometry: Keep visual and collision elements.
        mesh_formats: Lower-case file suffixes to keep (all when empty).

    Raises:
        RobotLoadError: The robot has no URDF, or a mesh URI cannot be resolved.
    """
    path = getattr(robot, "urdf_path", None)
    if not path:
        raise RobotLoadError(f"robot {robot.name!r} has no URDF to give a peer")
    tree = ET.parse(path)
    root = tree.getroot()
    keep = set(robot.joint_names)
    for joint in root.iter("joint"):
        if joint.get("type") != "fixed" and joint.get("name") not in keep:
            joint.set("type", "fixed")
    for link in root.iter("link"):
        for tag in ("visual", "collision"):
            for element in list(link.findall(tag)):
                mesh = element.find("geometry/mesh")
                drop = not keep_geometry
                if mesh is not None and not drop:
                    filename = resolve_package_uri(mesh.get("filename", ""), robot.package_dirs)
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


def pinocchio_model(robot: Robot) -> tuple[Any, int]:
    """Pinocchio model of ``robot`` and the index of its end-effector frame.

    A :class:`PinocchioArm` gives its own reduced model (the very model our backends use);
    a :class:`PlanarArm` is built from :func:`planar_urdf`.

    Raises:
        RobotLoadError: The robot is neither.
    """
    if isinstance(robot, PlanarArm):
        model = pin.buildModelFromXML(planar_urdf(robot))
        return model, int(model.getFrameId(PLANAR_FRAME, pin.FrameType.BODY))
    model = getattr(robot, "model", None)
    if isinstance(model, pin.Model):
        return model, int(robot.frame_id)  # type: ignore[attr-defined]
    raise RobotLoadError(f"robot {robot.name!r}: peers support PlanarArm and PinocchioArm only")


def mujoco_model(robot: Robot) -> tuple[Any, str]:
    """MuJoCo model of ``robot`` and the name of its end-effector site.

    Planar arms come from :func:`planar_mjcf`; URDF arms are loaded from
    :func:`peer_urdf` (absolute mesh paths, ``strippath="false"`` so MuJoCo keeps them,
    ``fusestatic="false"``) and get a site :data:`MUJOCO_SITE` on the body of the frame's
    parent joint, placed at the frame's Pinocchio placement in that joint frame.

    Raises:
        RobotLoadError: Unsupported robot or a URDF MuJoCo rejects.
    """
    import mujoco

    if isinstance(robot, PlanarArm):
        return mujoco.MjModel.from_xml_string(planar_mjcf(robot)), PLANAR_FRAME
    model, frame_id = pinocchio_model(robot)
    text = peer_urdf(robot, mesh_formats=MUJOCO_MESH_FORMATS)
    root = ET.fromstring(text)
    extension = ET.SubElement(root, "mujoco")
    ET.SubElement(
        extension, "compiler", strippath="false", fusestatic="false", discardvisual="true"
    )
    try:
        spec = mujoco.MjSpec.from_string(ET.tostring(root, encoding="unicode"))
    except ValueError as error:
        raise RobotLoadError(f"urdf: MuJoCo cannot load {robot.name!r}: {error}") from error
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
    return spec.compile(), MUJOCO_SITE


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


def pose_mismatch(robot: Robot, theta: FloatArray) -> tuple[float, float]:
    r"""How far Pinocchio and MuJoCo disagree on the end-effector pose at ``θ``.

    .. math:: e_p = \|p_{pin} - p_{mj}\|,\qquad e_R = \|\log(R_{pin}^\top R_{mj})\|

    Args:
        robot: Planar or Pinocchio arm.
        theta: Joint coordinates [rad], shape ``(nv,)``.

    Returns:
        ``(e_p [m], e_R [rad])``.
    """
    import mujoco

    model, frame_id = pinocchio_model(robot)
    q = pin.integrate(model, pin.neutral(model), np.asarray(theta, dtype=float))
    if not isinstance(robot, PlanarArm):
        q = robot.configuration(np.asarray(theta, dtype=float))
    pose_pin = pinocchio_frame_pose(model, frame_id, q)
    mj_model, site = mujoco_model(robot)
    mj_data = mujoco.MjData(mj_model)
    qpos = mujoco_joint_map(robot, mj_model).to_peer(theta, mj_model.qpos0)
    pose_mj = mujoco_site_pose(mj_model, mj_data, site, qpos)
    e_p = float(np.linalg.norm(pose_pin[:3, 3] - pose_mj[:3, 3]))
    e_r = float(np.linalg.norm(pin.log3(pose_pin[:3, :3].T @ pose_mj[:3, :3])))
    return e_p, e_r
