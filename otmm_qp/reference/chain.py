r"""The joints that move a frame, as a vectorised forward kinematics for many configurations.

A serial chain of ``m`` one-DoF joints (revolute or prismatic) from the world to a frame:

.. math::
    T(q) = \prod_{j=1}^{m} \big(P_j\, M_j(q_j)\big)\, T_{tip},\qquad
    M_j(q) = \begin{cases} \mathrm{Rot}(a_j, q) & \text{revolute} \\
    \mathrm{Trans}(q\, a_j) & \text{prismatic} \end{cases}

with ``P_j`` the joint's fixed placement in its parent joint's frame, ``a_j`` its unit axis
in its own frame and ``T_tip`` the frame's placement in the last joint's frame. The world
axis of joint ``j`` is ``ω_j = R_{j}(q) a_j`` and its origin ``o_j``; the position
Jacobian's column is ``ω_j × (p − o_j)`` (revolute) or ``ω_j`` (prismatic).

:func:`chain_of` reads it from a Pinocchio arm (the joints supporting the frame) or a planar
arm; :meth:`Chain.forward` evaluates ``M`` configurations at once with NumPy (one batched
4×4 product per joint), for the branch-and-bound enclosures of :mod:`.reach` and
:mod:`.sample_bound`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from otmm_qp.robots.robot import FloatArray, Robot

_AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}


class UnsupportedChain(ValueError):
    """The robot's frame is not moved by a serial chain of 1-DoF joints this module reads."""


@dataclass(frozen=True)
class Chain:
    """A serial chain of 1-DoF joints ending at a frame.

    Attributes:
        placements: ``P_j``, shape ``(m, 4, 4)``.
        axes: ``a_j`` (unit), shape ``(m, 3)``.
        prismatic: Whether joint ``j`` slides, shape ``(m,)``.
        columns: Joint ``j``'s index in the robot's joint coordinates, shape ``(m,)``.
        tip: ``T_tip``, shape ``(4, 4)``.
        nv: The robot's number of joint coordinates.
        dim: Task position dimension (3, or 2 for a planar arm).
    """

    placements: FloatArray
    axes: FloatArray
    prismatic: np.ndarray
    columns: np.ndarray
    tip: FloatArray
    nv: int
    dim: int = 3

    @property
    def size(self) -> int:
        """Number of joints ``m`` in the chain."""
        return int(self.axes.shape[0])

    def forward(self, q: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Frame pose and joint axes of ``M`` configurations.

        Args:
            q: Chain joint values, shape ``(M, m)`` [rad or m] (column ``j`` is joint ``j``
                of the chain, not of the robot).

        Returns:
            ``(p, R, origins, omegas)``: frame positions ``(M, 3)`` [m], frame rotations
            ``(M, 3, 3)``, joint origins ``(M, m, 3)`` [m] and world joint axes
            ``(M, m, 3)``.
        """
        count = q.shape[0]
        transform = np.broadcast_to(np.eye(4), (count, 4, 4)).copy()
        origins = np.empty((count, self.size, 3))
        omegas = np.empty((count, self.size, 3))
        for j in range(self.size):
            transform = transform @ self.placements[j]
            origins[:, j] = transform[:, :3, 3]
            axis = self.axes[j]
            omegas[:, j] = transform[:, :3, :3] @ axis
            if self.prismatic[j]:
                transform[:, :3, 3] += q[:, j, None] * omegas[:, j]
            else:
                transform[:, :3, :3] = transform[:, :3, :3] @ _rotations(axis, q[:, j])
        transform = transform @ self.tip
        return transform[:, :3, 3], transform[:, :3, :3], origins, omegas

    def jacobian(self, p: FloatArray, origins: FloatArray, omegas: FloatArray) -> FloatArray:
        """Position Jacobian columns ``∂p/∂q_j``, shape ``(M, m, 3)`` [m/rad or m/m]."""
        revolute = np.cross(omegas, p[:, None, :] - origins)
        return np.where(self.prismatic[None, :, None], omegas, revolute)

    def levers(self, lower: FloatArray, upper: FloatArray) -> FloatArray:
        r"""Per joint, a bound of ``‖∂p/∂q_j‖`` over the box ``lower ≤ q ≤ upper``, ``(m,)``.

        Revolute: the distance from ``p`` to the axis, at most the sum of the (invariant)
        distances between successive origins after it at ``q = 0`` plus the largest travel
        ``max(|l_i|, |u_i|)`` of every prismatic joint after it [m/rad]; prismatic: 1.
        """
        p, _, origins, _ = self.forward(np.zeros((1, self.size)))
        points = np.vstack([origins[0], p])
        offsets = np.linalg.norm(np.diff(points, axis=0), axis=1)
        travel = np.where(self.prismatic, np.maximum(np.abs(lower), np.abs(upper)), 0.0)
        after = np.cumsum((offsets + np.append(travel[1:], 0.0))[::-1])[::-1]
        return np.where(self.prismatic, 1.0, after)

    def spread(self, lower: FloatArray, upper: FloatArray) -> float:
        """A bound of ``‖p − o_1‖`` [m] over the box: every offset and every travel."""
        p, _, origins, _ = self.forward(np.zeros((1, self.size)))
        points = np.vstack([origins[0], p])
        travel = np.where(self.prismatic, np.maximum(np.abs(lower), np.abs(upper)), 0.0)
        return float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1)) + np.sum(travel))


def _rotations(axis: FloatArray, angles: FloatArray) -> FloatArray:
    """Rodrigues' rotations about the unit ``axis`` by ``angles`` [rad], shape ``(M, 3, 3)``."""
    cos = np.cos(angles)[:, None, None]
    sin = np.sin(angles)[:, None, None]
    cross = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + sin * cross + (1.0 - cos) * (cross @ cross)


def chain_of(robot: Robot) -> Chain:
    """The chain moving ``robot``'s frame (Pinocchio or planar arm).

    Raises:
        UnsupportedChain: Another kind of robot, or a joint that is not a 1-DoF revolute,
            continuous or prismatic joint with a readable axis.
    """
    from otmm_qp.robots.pinocchio_arm import PinocchioArm
    from otmm_qp.robots.planar_arm import PlanarArm

    if isinstance(robot, PlanarArm):
        return _planar_chain(np.array(robot.link_lengths, dtype=np.float64))
    if isinstance(robot, PinocchioArm):
        return _pinocchio_chain(robot)
    raise UnsupportedChain(f"no kinematic chain for a {type(robot).__name__}")


def _planar_chain(lengths: FloatArray) -> Chain:
    count = lengths.size
    placements = np.broadcast_to(np.eye(4), (count, 4, 4)).copy()
    placements[1:, 0, 3] = lengths[:-1]
    tip = np.eye(4)
    tip[0, 3] = lengths[-1]
    return Chain(
        placements,
        np.tile([0.0, 0.0, 1.0], (count, 1)),
        np.zeros(count, dtype=bool),
        np.arange(count),
        tip,
        count,
        dim=2,
    )


def _pinocchio_chain(robot: Robot) -> Chain:
    model = robot.model  # type: ignore[attr-defined]
    frame = model.frames[robot.frame_id]  # type: ignore[attr-defined]
    chain = [j for j in model.supports[frame.parentJoint] if j > 0]
    placements, axes, prismatic, columns = [], [], [], []
    for j in chain:
        joint = model.joints[j]
        kind = joint.shortname().removeprefix("JointModel")
        axis = _axis_of(joint, kind)
        if axis is None or joint.nv != 1:
            raise UnsupportedChain(f"joint {model.names[j]!r} ({kind}) has no readable axis")
        placements.append(np.asarray(model.jointPlacements[j].homogeneous, dtype=float))
        axes.append(axis)
        prismatic.append(kind.startswith("P"))
        columns.append(joint.idx_v)
    return Chain(
        np.array(placements).reshape(len(chain), 4, 4),
        np.array(axes, dtype=float).reshape(len(chain), 3),
        np.array(prismatic, dtype=bool),
        np.array(columns, dtype=int),
        np.asarray(frame.placement.homogeneous, dtype=float),
        int(model.nv),
    )


def _axis_of(joint: object, kind: str) -> FloatArray | None:
    """Unit axis of a revolute/prismatic joint model in its own frame, None if unknown."""
    for prefix in ("RUB", "R", "P"):
        if kind.startswith(prefix) and kind[len(prefix) :] in _AXES:
            return np.array(_AXES[kind[len(prefix) :]])
    if "Unaligned" in kind:
        extracted = joint.extract()  # type: ignore[attr-defined]
        axis: FloatArray = np.asarray(getattr(extracted, "axis", np.zeros(3)), dtype=np.float64)
        norm = float(np.linalg.norm(axis))
        return axis / norm if norm > 0.0 else None
    return None
