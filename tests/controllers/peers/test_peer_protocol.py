"""The peer protocol: any robot that describes itself (``peer_description``) runs with the peers.

The robots here are third-party ones: subclasses of :class:`Robot` that implement only the
base interface and :meth:`Robot.peer_description` (no PlanarArm / PinocchioArm involved). They
must give the peers exactly the problem our ``qp`` backend solves.
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Iterator
from importlib import metadata
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

from otmm_qp import registry
from otmm_qp.config.load import parse_config
from otmm_qp.exceptions import RobotLoadError
from otmm_qp.robots import PeerDescription, Robot
from otmm_qp.robots import peer_models as models
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.robots.robot import FloatArray, TaskKind
from otmm_qp.runner import run_suite
from otmm_qp.state import KinematicState

PEERS = {
    "pink": "otmm_qp_controllers.peers.pink_backend:PinkBackend",
    "mink": "otmm_qp_controllers.peers.mink_backend:MinkBackend",
    "drake": "otmm_qp_controllers.peers.drake_backend:DrakeBackend",
}
PEER_MODULES = {"pink": "pink", "mink": "mink", "drake": "pydrake"}
#: The third-party planar arm, registered as a robot plugin by :func:`plugins`.
PLUGIN_ROBOT = ("third_party_planar", "tests.controllers.peers.test_peer_protocol:UrdfPlanarArm")
#: Agreement of a peer's q̇ with qp's on one non-singular step [rad/s].
STEP_TOLERANCE = 1e-6
#: Tikhonov weight μ (``regularization``) of qp, pink and mink in the step comparison.
DAMPING = 1e-9

_INERTIAL = (
    '<inertial><mass value="1"/><origin xyz="0 0 0"/>'
    '<inertia ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/></inertial>'
)


def _planar_urdf(lengths: list[float], tool: float) -> str:
    """URDF of a planar arm: joints ``shoulder, elbow, wrist`` about z, a ``tool`` link."""
    names = ["shoulder", "elbow", "wrist"]
    parts = ['<robot name="third_party_planar">', f'<link name="base">{_INERTIAL}</link>']
    parent, offset = "base", 0.0
    for i, name in enumerate(names):
        parts += [
            f'<link name="link{i}">{_INERTIAL}</link>',
            f'<joint name="{name}" type="revolute"><parent link="{parent}"/>'
            f'<child link="link{i}"/><origin xyz="{offset} 0 0"/><axis xyz="0 0 1"/>'
            '<limit lower="-3" upper="3" effort="0" velocity="10"/></joint>',
        ]
        parent, offset = f"link{i}", lengths[i]
    parts += [
        f'<link name="tool">{_INERTIAL}</link>',
        f'<joint name="tool_joint" type="fixed"><parent link="{parent}"/><child link="tool"/>'
        f'<origin xyz="{offset + tool} 0 0"/></joint>',
        "</robot>",
    ]
    return "\n".join(parts)


class UrdfPlanarArm(Robot):
    """A third-party planar arm: closed-form kinematics, described to peers by its URDF only.

    Task: the ``(x, y)`` position [m] of the ``tool`` link (the last link extended by
    ``tool`` [m]); no MJCF, no Pinocchio model: each peer builds its own from the URDF.
    """

    name = "third_party_planar"
    task_kind: TaskKind = "position"

    def __init__(self, link_lengths: list[float], tool: float = 0.1) -> None:
        self._reach = np.array(link_lengths, dtype=float)
        self._reach[-1] += tool
        self._urdf = _planar_urdf(list(link_lengths), tool)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return ("shoulder", "elbow", "wrist")

    @property
    def task_dim(self) -> int:
        return 2

    @property
    def position_limits(self) -> tuple[FloatArray, FloatArray]:
        return np.full(3, -3.0), np.full(3, 3.0)

    @property
    def velocity_limits(self) -> FloatArray:
        return np.full(3, 10.0)

    def kinematics(self, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        theta = np.cumsum(q)
        links = self._reach * np.array([np.cos(theta), np.sin(theta)])  # (2, 3)
        outward = np.cumsum(links[:, ::-1], axis=1)[:, ::-1]  # Σ_{i≥j} link_i
        return outward[:, 0].copy(), np.array([-outward[1], outward[0]])

    def peer_description(self) -> PeerDescription:
        return PeerDescription(
            urdf=self._urdf, frame="tool", joint_names=self.joint_names, planar=True
        )


class ReversedUrdfArm(Robot):
    """A third-party 3-D arm over any URDF: its own Pinocchio kinematics, joints reversed.

    Our coordinate ``j`` is the URDF's movable joint ``nv − 1 − j``, so a peer that mapped
    by position instead of by name would get the wrong answer. Revolute joints only.
    """

    def __init__(self, urdf_path: str, package_dirs: list[str], frame: str, task: TaskKind) -> None:
        with open(urdf_path, encoding="utf-8") as handle:
            self._urdf = handle.read()
        self._package_dirs = tuple(package_dirs)
        self._frame = frame
        self.name = f"reversed_{os.path.splitext(os.path.basename(urdf_path))[0]}"
        self.task_kind = task
        self._model = pin.buildModelFromXML(self._urdf)
        self._data = self._model.createData()
        self._frame_id = self._model.getFrameId(frame)
        self._names = tuple(str(n) for n in reversed(list(self._model.names)[1:]))
        self._order = np.array([self._model.getJointId(n) - 1 for n in self._names])

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self._names

    @property
    def task_dim(self) -> int:
        return 6 if self.task_kind == "pose" else 3

    @property
    def position_limits(self) -> tuple[FloatArray, FloatArray]:
        lower = np.asarray(self._model.lowerPositionLimit)[self._order]
        return lower, np.asarray(self._model.upperPositionLimit)[self._order]

    @property
    def velocity_limits(self) -> FloatArray:
        return np.asarray(self._model.velocityLimit)[self._order]

    def kinematics(self, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        q_urdf = np.empty(self._model.nq)
        q_urdf[self._order] = q
        pin.forwardKinematics(self._model, self._data, q_urdf)
        pose = pin.updateFramePlacement(self._model, self._data, self._frame_id)
        jacobian = pin.computeFrameJacobian(
            self._model, self._data, q_urdf, self._frame_id, pin.LOCAL_WORLD_ALIGNED
        )[:, self._order]
        if self.task_kind == "pose":
            return pose.homogeneous.copy(), jacobian
        return pose.translation.copy(), jacobian[:3]

    def task_error(self, x_target: FloatArray, x: FloatArray) -> FloatArray:
        if self.task_kind == "position":
            return super().task_error(x_target, x)
        error = np.empty(6)
        error[:3] = x_target[:3, 3] - x[:3, 3]
        error[3:] = pin.log3(x_target[:3, :3] @ x[:3, :3].T)
        return error

    def peer_description(self) -> PeerDescription:
        return PeerDescription(
            urdf=self._urdf,
            frame=self._frame,
            joint_names=self.joint_names,
            package_dirs=self._package_dirs,
        )


class UndescribedArm(Robot):
    """A third-party robot that implements the base interface only (no peer_description)."""

    name = "mystery_arm"

    @property
    def joint_names(self) -> tuple[str, ...]:
        return ("a", "b")

    @property
    def task_dim(self) -> int:
        return 2

    @property
    def position_limits(self) -> tuple[FloatArray, FloatArray]:
        return np.full(2, -np.inf), np.full(2, np.inf)

    @property
    def velocity_limits(self) -> FloatArray:
        return np.full(2, np.inf)

    def kinematics(self, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        return PlanarArm([1.0, 1.0]).kinematics(q)


def ur5(task: TaskKind) -> ReversedUrdfArm:
    """UR5 from example-robot-data, as a third party would load it."""
    from example_robot_data.robots_loader import getModelPath

    relative = "ur_description/urdf/ur5_robot.urdf"
    robots_dir = str(getModelPath(relative))
    package_dir = os.path.normpath(os.path.join(robots_dir, "..", ".."))
    return ReversedUrdfArm(os.path.join(robots_dir, relative), [package_dir], "tool0", task)


@pytest.fixture
def plugins(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Register the peers and :class:`UrdfPlanarArm` as entry points, as a package would."""
    original = metadata.entry_points
    extra = {registry.BACKENDS: PEERS, registry.ROBOTS: dict([PLUGIN_ROBOT])}

    def patched(**params: Any) -> Any:
        found = original(**params)
        wanted = extra.get(params.get("group", ""), {})
        present = {e.name for e in found}
        added = [
            metadata.EntryPoint(name, value, params["group"])
            for name, value in wanted.items()
            if name not in present
        ]
        return metadata.EntryPoints([*found, *added]) if added else found

    monkeypatch.setattr(metadata, "entry_points", patched)
    registry.clear_cache()
    yield
    registry.clear_cache()


def damping(peer: str) -> dict[str, float]:
    """The Tikhonov weight of ``peer`` set to :data:`DAMPING` (Drake has none)."""
    return {} if peer == "drake" else {"regularization": DAMPING}


def one_step(robot: Robot, theta: FloatArray, peer: str, weight: FloatArray | None = None) -> Any:
    """``(peer q̇, qp q̇)`` [rad/s] on one step at ``θ`` with a small task velocity."""
    from otmm_qp_controllers.peers.drake_backend import DrakeBackend
    from otmm_qp_controllers.peers.mink_backend import MinkBackend
    from otmm_qp_controllers.peers.pink_backend import PinkBackend

    peers: dict[str, Any] = {"pink": PinkBackend, "mink": MinkBackend, "drake": DrakeBackend}
    w = np.ones(robot.task_dim) if weight is None else weight
    state = KinematicState.compute(robot, robot.configuration(theta), w)
    xdot = w * np.linspace(0.05, -0.04, robot.task_dim)  # weighted, as a filter passes it
    answers = []
    for backend in (
        peers[peer](**damping(peer)),
        registry.create(
            registry.BACKENDS, "qp", {"solver": "daqp", "regularization": DAMPING}, "qp"
        ),
    ):
        backend.bind(robot, 0.01)
        backend.reset()
        answers.append(backend.solve(state, xdot, np.zeros(robot.nv)).qdot)
    assert np.min(state.sigma) > 0.1  # non-singular: the damping does not matter
    return answers


# ------------------------------------------------------------- third-party robots
@pytest.mark.parametrize("peer", sorted(PEERS))
def test_third_party_planar_robot_matches_qp(peer: str) -> None:
    pytest.importorskip(PEER_MODULES[peer])
    robot = UrdfPlanarArm([1.0, 0.8, 0.5])
    theirs, ours = one_step(robot, np.array([0.3, 0.9, -0.7]), peer)
    np.testing.assert_allclose(theirs, ours, atol=STEP_TOLERANCE)
    assert np.max(np.abs(ours)) > 1e-2  # a real motion, not two zeros


@pytest.mark.parametrize("task", ["position", "pose"])
@pytest.mark.parametrize("peer", sorted(PEERS))
def test_third_party_urdf_robot_with_reordered_joints_matches_qp(peer: str, task: str) -> None:
    pytest.importorskip(PEER_MODULES[peer])
    robot = ur5(task)  # type: ignore[arg-type]
    weight = np.array([2.0, 1.0, 0.5, 0.3, 0.2, 0.4])[: robot.task_dim]
    theta = np.array([0.3, 1.5, -1.8, 1.5, -1.2, 0.2])  # reversed UR5 order, wrist 5 ≠ 0
    theirs, ours = one_step(robot, theta, peer, weight if peer != "drake" else None)
    np.testing.assert_allclose(theirs, ours, atol=STEP_TOLERANCE)


def test_reordered_joints_are_mapped_by_name() -> None:
    """The reversed arm's q̇ really differs from the URDF order (the previous test can fail)."""
    pytest.importorskip("pink")
    robot = ur5("pose")
    theirs, _ = one_step(robot, np.array([0.3, 1.5, -1.8, 1.5, -1.2, 0.2]), "pink")
    assert np.max(np.abs(theirs - theirs[::-1])) > 1e-2


@pytest.mark.parametrize("peer", sorted(PEERS))
def test_third_party_robot_plugin_runs_with_the_peer_in_a_suite(plugins: None, peer: str) -> None:
    pytest.importorskip(PEER_MODULES[peer])
    experiment = {
        "name": "third_party_circle",
        "robot": {"type": PLUGIN_ROBOT[0], "link_lengths": [1.0, 0.8, 0.5]},
        "q0": [0.3, 0.9, -0.7],
        "trajectory": {"type": "circle", "centre": [1.67, 1.33], "radius": 0.1, "period": 2.0},
        "duration": 0.5,
        "controllers": [
            {"name": peer, "backend": {"type": peer} | damping(peer)},
            {"name": "qp", "backend": {"type": "qp", "solver": "daqp", "regularization": DAMPING}},
        ],
    }
    suite = parse_config(
        {"version": 2, "name": "p", "loop_modes": ["clik"], "experiments": [experiment]}
    )
    outcome = run_suite(suite, None, progress=None)
    assert outcome.errors == [] and outcome.skipped == []
    ours = outcome.find("third_party_circle", "clik", "qp")
    theirs = outcome.find("third_party_circle", "clik", peer)
    assert ours is not None and theirs is not None
    assert float(np.max(np.abs(theirs.result.q - ours.result.q))) <= 1e-6  # [rad]


def test_third_party_planar_urdf_agrees_with_its_mujoco_model() -> None:
    pytest.importorskip("mujoco")
    robot = UrdfPlanarArm([1.0, 0.8, 0.5])
    theta = np.array([0.4, -0.7, 1.1])
    position, orientation = models.pose_mismatch(robot, theta)
    assert position < 1e-12 and orientation < 1e-12
    pinocchio = models.PinocchioPeerModel.create(robot.peer_description(), robot)
    pose = models.pinocchio_frame_pose(pinocchio.model, pinocchio.frame_id, theta)
    np.testing.assert_allclose(pose[:2, 3], robot.forward(theta), atol=1e-12)


# ------------------------------------------------------------ refusals, one line each
def test_robot_without_peer_description_is_refused_in_one_line() -> None:
    with pytest.raises(RobotLoadError) as caught:
        UndescribedArm().peer_description()
    message = str(caught.value)
    assert "\n" not in message
    assert "'mystery_arm'" in message and "UndescribedArm" in message
    assert "implement peer_description()" in message


@pytest.mark.parametrize("peer", sorted(PEERS))
def test_every_peer_refuses_an_undescribed_robot_at_bind(peer: str) -> None:
    pytest.importorskip(PEER_MODULES[peer])
    module, _, name = PEERS[peer].partition(":")
    backend_cls = getattr(importlib.import_module(module), name)
    with pytest.raises(RobotLoadError, match=r"^robot 'mystery_arm' \(UndescribedArm\)"):
        backend_cls().bind(UndescribedArm(), 0.01)


def test_a_description_that_contradicts_the_robot_is_refused() -> None:
    class Renamed(UrdfPlanarArm):
        def peer_description(self) -> PeerDescription:
            return PeerDescription(self._urdf, "tool", ("elbow", "shoulder", "wrist"), True)

    class NotPlanar(UrdfPlanarArm):
        def peer_description(self) -> PeerDescription:
            return PeerDescription(self._urdf, "tool", self.joint_names, planar=False)

    with pytest.raises(RobotLoadError, match=r"joint_names \['elbow', 'shoulder', 'wrist'\]"):
        models.describe(Renamed([1.0, 1.0, 1.0]))
    with pytest.raises(RobotLoadError, match=r"3 task rows .* but task_dim is 2"):
        models.describe(NotPlanar([1.0, 1.0, 1.0]))
    with pytest.raises(RobotLoadError, match="both pinocchio_model and frame_id"):
        PeerDescription("<robot/>", "tool", ("a",), frame_id=3)


# ------------------------------------------------------------ built-in robots
def test_built_in_robots_describe_themselves() -> None:
    planar = PlanarArm([1.0, 0.5]).peer_description()
    assert planar.planar and planar.mjcf is not None and planar.pinocchio_model is None
    assert planar.frame == models.PLANAR_FRAME and planar.joint_names == ("joint1", "joint2")
    arm = PinocchioArm(name="panda")
    pose = arm.peer_description()
    assert not pose.planar and pose.pinocchio_model is arm.model and pose.frame_id == arm.frame_id
    assert pose.joint_names == arm.joint_names and pose.package_dirs
    assert "package://" in pose.urdf  # resolved by the peers against package_dirs
