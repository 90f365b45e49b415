r"""The wrist bound of pose tasks: points the tool carries that the arm cannot bring there.

The origin ``o_m`` of the chain's last joint (on its axis, where Pinocchio puts it) is fixed
in the frame's coordinates *and* does not move with that joint; the origin ``o_{m−1}`` of the
joint before turns, in the frame's coordinates, on a circle about the last joint's axis as
that joint turns. Both are points of the chain without its last one or two joints, whose
certified reach ``‖o(q) − b‖ ≤ ρ`` over the joint box comes from the branch and bound of
:mod:`.reach` (``b`` the first joint's origin). In the frame's coordinates each is on a
circle ``Y`` (centre ``y_c``, axis ``n``, radius ``r``; ``r = 0`` for ``o_m``), and in the
world on ``C(q) = p(q) + R(q) Y``.

A configuration whose frame is within ``g t_p`` of ``p*`` and turned by at most ``g t_r``
from ``R*`` moves every point ``y`` of ``Y`` by ``‖(p + R y) − (p* + R* y)‖ ≤ g t_p + 2 ‖y‖
\sin(\min(g t_r, π)/2)``, so with ``C* = p* + R* Y`` and ``‖y‖ ≤ ‖y_c‖ + r``,

.. math:: ‖o(q) − b‖ \ge d(b, C^*) − f(g), \qquad
          f(g) = g\,t_p + 2 (‖y_c‖ + r) \sin(\min(g t_r, π)/2),

``d(b, C*) = sqrt(a² + (ρ_⊥ − r)²)`` (``a``, ``ρ_⊥`` the parts of ``b − c*`` along and across
the circle's axis). Where the gap ``G = d(b, C*) − ρ`` is positive, every configuration has
``m_k > g`` for each ``g`` with ``f(g) < G``: the bound is the root of ``f(g) = G`` (``f``
increases), found by bisection and rounded inward; the largest over the points.

It decides pose targets whose position is reachable and whose orientation is reachable, but
not both at once: the tool pointing *out* at the edge of the workspace puts the wrist past
its reach. Position tasks, a pose task without both tolerances or a chain of one joint: no
bound (0); a prismatic joint among the last two ends the list of points there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from otmm_qp.reference.chain import Chain, UnsupportedChain, chain_of
from otmm_qp.reference.reach import (
    DegenerateReach,
    ReachCertificate,
    certify,
    joint_box,
)
from otmm_qp.robots.robot import FloatArray, Robot

#: Bisection steps of the root of ``f(g) = G`` (far below the float resolution of ``g``).
BISECTION = 80
#: Relative and absolute room taken off the gap [m] and the bound against rounding.
ROUNDING = 1e-9


@dataclass(frozen=True)
class CarriedPoint:
    """A joint origin the frame carries on a circle, and its certified reach.

    Attributes:
        centre: ``y_c``, the circle's centre in the frame's coordinates [m], shape ``(3,)``.
        axis: ``n``, its unit axis in the frame's coordinates, shape ``(3,)``.
        radius: ``r`` [m] (0: a point fixed in the frame).
        base: ``b`` [m], shape ``(3,)``.
        outer: ``ρ``, certified ``max ‖o(q) − b‖`` over the joint box [m].
        certificate: The reach certificate of the shorter chain.
    """

    centre: FloatArray
    axis: FloatArray
    radius: float
    base: FloatArray
    outer: float
    certificate: ReachCertificate


def shorter_chain(chain: Chain, drop: int) -> Chain:
    """The chain without its last ``drop`` joints, its tip at the next joint's origin."""
    keep = chain.size - drop
    return Chain(
        chain.placements[:keep],
        chain.axes[:keep],
        chain.prismatic[:keep],
        chain.columns[:keep],
        chain.placements[keep],
        chain.nv,
        chain.dim,
    )


def carried_points(robot: Robot, store: Path | None = None) -> tuple[CarriedPoint, ...]:
    """The origins of the last joint and the one before it, as the frame carries them.

    Their reach certificates are cached per model by :func:`~.reach.certify` (in memory, and
    in ``store`` when given), so a call after the first only reads the chain. Empty: no
    readable chain, a planar arm (no orientation), a chain of one joint; a prismatic last
    joint (the points slide along it) gives none, a prismatic joint before it only the first.
    """
    try:
        chain = chain_of(robot)
    except UnsupportedChain:
        return ()
    if chain.size < 2 or chain.dim != 3 or bool(chain.prismatic[-1]):
        return ()
    tip_rotation, tip_translation = chain.tip[:3, :3], chain.tip[:3, 3]
    axis = tip_rotation.T @ chain.axes[-1]
    points: list[CarriedPoint] = []
    for drop in (1, 2):
        if chain.size - drop < 1 or (drop == 2 and bool(chain.prismatic[-2])):
            break
        if drop == 1:
            local = np.zeros(3)  # o_m in the last joint's frame
        else:  # o_{m−1} in the last joint's frame before it turns
            placement = chain.placements[-1]
            local = -placement[:3, :3].T @ placement[:3, 3]
        along = float(chain.axes[-1] @ local)
        radius = float(np.linalg.norm(local - along * chain.axes[-1]))
        shorter = shorter_chain(chain, drop)
        try:
            lower, upper = joint_box(shorter, robot)
        except DegenerateReach:
            break
        certificate = certify(shorter, lower, upper, store)
        points.append(
            CarriedPoint(
                centre=tip_rotation.T @ (along * chain.axes[-1] - tip_translation),
                axis=axis,
                radius=radius,
                base=np.array(certificate.base, dtype=float),
                outer=certificate.outer,
                certificate=certificate,
            )
        )
    return tuple(points)


def wrist_merits(
    points: tuple[CarriedPoint, ...],
    positions: FloatArray,
    rotations: FloatArray,
    position_tolerance: float,
    orientation_tolerance: float,
) -> FloatArray:
    """Per sample, a certified lower bound of ``m_k`` [tolerances] (0 where no gap is > 0).

    Args:
        points: The robot's :func:`carried_points`.
        positions: Targets ``p*_k`` [m], shape ``(N, 3)``.
        rotations: Targets ``R*_k``, shape ``(N, 3, 3)``.
        position_tolerance: ``t_p`` [m].
        orientation_tolerance: ``t_r`` [rad].
    """
    best = np.zeros(positions.shape[0])
    for point in points:
        centres = positions + rotations @ point.centre
        axes = rotations @ point.axis
        gap = _distance(point.base, centres, axes, point.radius) - point.outer
        gap = gap * (1.0 - ROUNDING) - ROUNDING
        size = float(np.linalg.norm(point.centre)) + point.radius
        best = np.maximum(best, _root(gap, size, position_tolerance, orientation_tolerance))
    return best


def _distance(
    point: FloatArray, centres: FloatArray, axes: FloatArray, radius: float
) -> FloatArray:
    """Distance [m] from ``point`` ``(3,)`` to circles, shape ``(N,)``.

    Circles of centres ``(N, 3)``, unit axes ``(N, 3)`` and ``radius`` [m]:
    ``sqrt(a² + (ρ_⊥ − r)²)``.
    """
    offset = point[None, :] - centres
    along = np.einsum("nd,nd->n", offset, axes)
    across = np.linalg.norm(offset - along[:, None] * axes, axis=1)
    return np.asarray(np.hypot(along, across - radius), dtype=float)


def _root(gap: FloatArray, size: float, position: float, orientation: float) -> FloatArray:
    """Largest ``g`` (rounded inward) with ``f(g) < gap``, ``f`` of the module docstring."""

    def reach(g: FloatArray) -> FloatArray:
        angle = np.minimum(g * orientation, math.pi)
        return g * position + 2.0 * size * np.sin(0.5 * angle)

    low = np.zeros_like(gap)
    high = np.maximum(gap, 0.0) / position  # f(g) ≥ g t_p
    for _ in range(BISECTION):
        middle = 0.5 * (low + high)
        below = reach(middle) < gap
        low = np.where(below, middle, low)
        high = np.where(below, high, middle)
    return np.where(gap > 0.0, low * (1.0 - ROUNDING), 0.0)
