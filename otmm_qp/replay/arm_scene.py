"""The MeshCat scene of a URDF arm, recorded without a server.

Pinocchio's :class:`pinocchio.visualize.MeshcatVisualizer` loads the robot's visual meshes
into a :class:`meshcat.Visualizer`; here the visualizer's window *records* the packed
MeshCat commands instead of sending them over ZMQ, so no server process is started. The
replay page replays these commands into MeshCat's own viewer bundle (``main.min.js``,
shipped in the ``meshcat`` wheel) and then sets the recorded per-frame transforms.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from otmm_qp.robots.robot import FloatArray, Robot

#: Column-major entries of a 4×4 transform kept per geometry and frame (last row is 0 0 0 1).
_AFFINE_ENTRIES = [0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14]
ROBOT_NODE = "robot"


def import_meshcat() -> Any:
    """``meshcat``, imported without the pyzmq deprecation warning its server module raises."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        import meshcat
        import meshcat.geometry
        import pinocchio.visualize  # noqa: F401  (imports meshcat's server module too)
    return meshcat


class RecordingWindow:
    """Stands in for meshcat's ``ViewerWindow``: keeps packed commands instead of sending them.

    Attributes:
        commands: msgpack-packed MeshCat commands, in order.
        capture: When not None, ``set_transform`` commands are stored here by path instead.
    """

    def __init__(self) -> None:
        self.commands: list[bytes] = []
        self.capture: dict[str, list[float]] | None = None

    def send(self, command: Any) -> None:
        """Record one MeshCat command (the interface of ``meshcat.visualizer.ViewerWindow``)."""
        import umsgpack

        data = command.lower()
        if self.capture is not None and data.get("type") == "set_transform":
            self.capture[str(data["path"])] = [float(v) for v in data["matrix"]]
            return
        self.commands.append(umsgpack.packb(data))


@dataclass
class ArmScene:
    """Recorded scene commands and per-frame geometry transforms of one arm.

    Attributes:
        commands: Packed MeshCat commands that build the scene (meshes, lines, markers).
        geometry_paths: MeshCat path of each moving geometry, length ``G``.
        warnings: Messages for the user (e.g. meshes missing, simple shapes used).
        uses_meshes: Whether the robot's own meshes are shown.
    """

    commands: list[bytes]
    geometry_paths: list[str]
    warnings: list[str] = field(default_factory=list)
    uses_meshes: bool = True


def _missing_meshes(geometry_model: Any) -> list[str]:
    return [
        str(g.meshPath)
        for g in geometry_model.geometryObjects
        if str(g.meshPath)
        and not os.path.isfile(str(g.meshPath))
        and not str(g.meshPath).startswith("BOX")
    ]


def _primitive_model(robot: Any) -> Any:
    """Simple shapes: a capsule per link segment (joint origin to joint origin) and spheres."""
    import coal
    import pinocchio as pin

    model = robot.model
    geometry = pin.GeometryModel()
    radius = 0.04

    def segment(name: str, joint: int, offset: FloatArray) -> None:
        length = float(np.linalg.norm(offset))
        if length < 1e-6:
            return
        axis = offset / length
        rotation = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), axis).matrix()
        placement = pin.SE3(rotation, offset / 2.0)
        obj = pin.GeometryObject(name, joint, placement, coal.Capsule(radius, length))
        obj.meshColor = np.array([0.75, 0.75, 0.78, 1.0])
        geometry.addGeometryObject(obj)

    for joint in range(1, model.njoints):
        parent = model.parents[joint]
        offset = np.asarray(model.jointPlacements[joint].translation, dtype=float)
        segment(f"link_{joint}", parent, offset)
        sphere = pin.GeometryObject(
            f"joint_{joint}", joint, pin.SE3.Identity(), coal.Sphere(radius * 1.3)
        )
        sphere.meshColor = np.array([0.35, 0.45, 0.6, 1.0])
        geometry.addGeometryObject(sphere)
    frame = model.frames[robot.frame_id]
    tip = np.asarray(frame.placement.translation, dtype=float)
    segment("tool", int(frame.parentJoint), tip)
    return geometry


def _visual_model(robot: Any) -> tuple[Any, list[str]]:
    """The robot's visual geometry, or simple shapes with a warning when meshes are missing."""
    import pinocchio as pin

    problem = ""
    geometry = None
    if robot.urdf_path:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                geometry = pin.buildGeomFromUrdf(
                    robot.model,
                    robot.urdf_path,
                    pin.GeometryType.VISUAL,
                    package_dirs=list(robot.package_dirs),
                )
        except (RuntimeError, ValueError, OSError) as error:
            problem = str(error).strip().splitlines()[0] if str(error).strip() else repr(error)
            geometry = None
    if geometry is not None:
        missing = _missing_meshes(geometry)
        if missing:
            problem = f"mesh file not found: {missing[0]}"
            geometry = None
        elif geometry.ngeoms == 0:
            problem = "the URDF has no visual geometry"
            geometry = None
    if geometry is None:
        message = (
            f"warning: robot {robot.name!r}: meshes unavailable ({problem or 'no URDF'}); "
            "showing simple shapes (capsules between joints) instead"
        )
        return _primitive_model(robot), [message]
    return geometry, []


def _line(points: FloatArray, color: int, width: float) -> tuple[Any, Any]:
    g = import_meshcat().geometry
    finite = points[np.all(np.isfinite(points), axis=1)]
    return (
        g.Line(
            g.PointsGeometry(finite.T.astype(np.float32)),
            g.LineBasicMaterial(color=color, linewidth=width),
        ),
        None,
    )


def build_arm_scene(
    robot: Robot,
    desired: FloatArray,
    actual_paths: Sequence[FloatArray],
    path_colors: Sequence[int],
) -> tuple[ArmScene, Any, RecordingWindow]:
    """Record the robot, the desired path and each controller's actual end-effector path.

    Args:
        robot: A :class:`~otmm_qp.robots.pinocchio_arm.PinocchioArm`.
        desired: Desired end-effector positions [m], shape ``(N, 3)``.
        actual_paths: Actual end-effector positions [m] per controller, shapes ``(N_c, 3)``.
        path_colors: 0xRRGGBB colour of each actual path.

    Returns:
        The scene, the pinocchio visualizer (for :func:`geometry_transforms`) and its window.
    """
    meshcat = import_meshcat()
    g = meshcat.geometry
    from pinocchio.visualize import MeshcatVisualizer

    arm: Any = robot
    geometry, messages = _visual_model(arm)
    window = RecordingWindow()
    viewer = meshcat.Visualizer(window=window)
    visualizer = MeshcatVisualizer(arm.model, None, geometry)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # pinocchio warns per unsupported object; checked above
        visualizer.initViewer(viewer=viewer)
        visualizer.loadViewerModel(rootNodeName=ROBOT_NODE)
    line, _ = _line(desired, 0x1B9E3A, 3.0)
    viewer["paths/desired"].set_object(line)
    for i, (points, color) in enumerate(zip(actual_paths, path_colors, strict=True)):
        line, _ = _line(points, color, 2.0)
        viewer[f"paths/actual_{i}"].set_object(line)
    viewer["markers/actual"].set_object(g.Sphere(0.012), g.MeshLambertMaterial(color=0xD81B60))
    viewer["markers/desired"].set_object(
        g.Sphere(0.01), g.MeshLambertMaterial(color=0x1B9E3A, opacity=0.8, transparent=True)
    )
    paths = [
        "/meshcat/" + visualizer.getViewerNodeName(obj, _visual_type())
        for obj in geometry.geometryObjects
    ]
    scene = ArmScene(window.commands, paths, messages, uses_meshes=not messages)
    return scene, visualizer, window


def _visual_type() -> Any:
    import pinocchio as pin

    return pin.GeometryType.VISUAL


def geometry_transforms(visualizer: Any, robot: Robot, q: FloatArray) -> FloatArray:
    """Placement of every visual geometry at each stored configuration.

    The same transform pinocchio's ``MeshcatVisualizer.display`` sends, computed directly:
    ``T = oMg · diag(scale, 1)`` (``updateGeometryPlacements`` then the mesh scale).

    Args:
        visualizer: The visualizer returned by :func:`build_arm_scene`.
        robot: The arm (converts joint coordinates to configurations).
        q: Joint coordinates [rad], shape ``(F, nv)``; non-finite rows repeat the previous one.

    Returns:
        Column-major affine entries, shape ``(F, G, 12)`` (float32).
    """
    import pinocchio as pin

    from otmm_qp.replay.robot_model import joint_configuration

    model, data = visualizer.model, visualizer.data
    geometry, geometry_data = visualizer.visual_model, visualizer.visual_data
    scales = [
        np.diag(np.append(np.asarray(g.meshScale, dtype=float), 1.0))
        for g in geometry.geometryObjects
    ]
    out = np.zeros((q.shape[0], geometry.ngeoms, 12), dtype=np.float32)
    last = np.zeros(q.shape[1])
    for k, row in enumerate(q):
        if np.all(np.isfinite(row)):
            last = row
        pin.forwardKinematics(model, data, joint_configuration(robot, last))
        pin.updateGeometryPlacements(model, data, geometry, geometry_data)
        for i in range(geometry.ngeoms):
            matrix = geometry_data.oMg[i].homogeneous @ scales[i]
            out[k, i] = matrix.T.reshape(16)[_AFFINE_ENTRIES]
    return out
