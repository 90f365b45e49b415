r"""What a robot hands a peer IK library (pink, mink, Drake) so the peer can model the same arm.

A peer does not use :meth:`Robot.kinematics`: it builds its own model of the arm from a
:class:`PeerDescription` that the robot returns from :meth:`Robot.peer_description`. The
description is plain data (no Pinocchio, MuJoCo or Drake import is needed to build it), so a
third-party robot only has to say where its URDF is, which frame is the end effector and how
its joints are named.

The task a peer commands follows from the description and :attr:`Robot.task_kind`:

=========================  ==========================================  =========
description / task kind    commanded rows of the frame twist (v, ω)    task_dim
=========================  ==========================================  =========
``planar=True``            ``(vx, vy)`` of the frame origin, world xy  2
``"position"``             ``(vx, vy, vz)``                            3
``"pose"``                 ``(vx, vy, vz, ωx, ωy, ωz)``                6
=========================  ==========================================  =========

(linear velocity [m/s] of the frame origin and angular velocity [rad/s], world axes: the
``LOCAL_WORLD_ALIGNED`` Jacobian rows, which is what :meth:`Robot.kinematics` must return.)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from otmm_qp.exceptions import RobotLoadError


@dataclass(frozen=True)
class PeerDescription:
    """The model a peer builds of a robot, as URDF/MJCF text and names.

    Attributes:
        urdf: URDF XML text of the arm, base fixed to the world. Mesh URIs must be absolute
            paths or ``package://PKG/rel`` URIs found under :attr:`package_dirs`. Movable
            joints not in :attr:`joint_names` are welded (``fixed`` at their zero position)
            by the peers.
        frame: End-effector frame: a URDF link name (or any frame name of
            :attr:`pinocchio_model`); in :attr:`mjcf`, the name of the end-effector site.
        joint_names: URDF names of the robot's ``nv`` joints, in the robot's coordinate
            order: must equal :attr:`Robot.joint_names`. Joint coordinate ``i``
            (:meth:`Robot.joint_coordinates`, [rad] or [m]) is the position of URDF joint
            ``joint_names[i]``, same zero. Peers map coordinates by name, so the URDF may order
            its joints differently.
        planar: The task is the ``(x, y)`` position [m] of the frame in the world xy-plane
            (``task_dim == 2``). False: a 3-D position (``task_kind="position"``) or a pose
            (``task_kind="pose"``).
        package_dirs: Directories searched for ``package://`` URIs (each holding ``PKG/``).
        pinocchio_model: Optional ``pinocchio.Model`` of the arm whose configuration vector
            *is* the robot's ``q`` (nq,) and whose joints (after the universe) are
            :attr:`joint_names` in order, e.g. the reduced model of a
            :class:`~otmm_qp.robots.pinocchio_arm.PinocchioArm` (locked joints at their lock
            values). Pink and the frame placement of mink and Drake use it instead of
            building a model from :attr:`urdf`; its limits are not read (peers use the
            robot's :attr:`~Robot.position_limits` and :attr:`~Robot.velocity_limits`).
        frame_id: Index of the end-effector frame in ``pinocchio_model.frames``; required
            with, and only with, :attr:`pinocchio_model`.
        mjcf: Optional MJCF XML text (angles in radians) of the arm for MuJoCo (mink), with a
            site named :attr:`frame` at the end effector and hinge/slide joints named as in
            :attr:`joint_names`. When None, mink loads :attr:`urdf`.
    """

    urdf: str
    frame: str
    joint_names: tuple[str, ...]
    planar: bool = False
    package_dirs: tuple[str, ...] = ()
    pinocchio_model: Any = None
    frame_id: int | None = None
    mjcf: str | None = None

    def __post_init__(self) -> None:
        """Normalise sequences to tuples and check the model/frame-id pairing.

        Raises:
            RobotLoadError: Exactly one of ``pinocchio_model`` and ``frame_id`` is given.
        """
        object.__setattr__(self, "joint_names", tuple(str(n) for n in self.joint_names))
        object.__setattr__(self, "package_dirs", tuple(str(d) for d in self.package_dirs))
        if (self.pinocchio_model is None) != (self.frame_id is None):
            raise RobotLoadError(
                "PeerDescription: give both pinocchio_model and frame_id, or neither"
            )
