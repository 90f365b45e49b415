r"""Certified per-sample lower bounds by branch and bound over the speed-reachable box.

By sample ``k`` every path within the limits is in the box

.. math:: B_k = [l, u] \cap [q_0 - k s,\; q_0 + k s], \qquad s = v_{max}\,dt

(a revolute range wider than 2π is the circle ``[c − π, c + π]``: the kinematics are
2π-periodic), so ``min_{q ∈ B_k} m_k(q)`` bounds the path's ``m_k`` from below. Joints that
do not move the frame are left out.

**Enclosure** of ``m_k`` on a box of centre ``c`` and half-widths ``h`` (chain joints):

* position, the largest of a first-order and two second-order forms [m]:
  ``‖e_pos(q)‖ ≥ ‖e_pos(c)‖ − Σ_i λ_i min(h_i, 2)`` (moving the joints one after another,
  revolute ``i`` moves the frame along a chord ``≤ λ_i min(h_i, 2)``; prismatic by ``h_i``),
  and ``‖e_pos(q)‖ ≥ ‖e_pos(c)‖ − Σ_i ‖J_i(c)‖ h_i − ½ Σ_ij λ_{max(i,j)} h_i h_j``
  (Taylor with ``‖∂²p/∂q_i∂q_j‖ ≤ λ_{max(i,j)}``, see :mod:`.reach`), and the same along
  the error's direction ``u = e_pos(c)/‖e_pos(c)‖``: ``‖e_pos(q)‖ ≥ u·e_pos(q) ≥ ‖e_pos(c)‖
  − Σ_i |u·J_i(c)| h_i − ½ Σ_ij λ_{max(i,j)} h_i h_j`` (the columns across ``u`` do not count);
* orientation [rad] (bi-invariance of the geodesic distance, each revolute joint turns the
  frame by at most its angle): ``‖e_rot(q)‖ ≥ ‖e_rot(c)‖ − Σ_{revolute} min(h_i, π)``;

``m_k ≥ max(pos/tol_pos, rot/tol_rot)`` with those, less ``ROUNDING`` against the
floating-point kinematics.

**Branch and bound**: the boxes with the smallest enclosure are halved (along the coordinate
with the largest share of it) in batches; a box whose enclosure is above the best centre
value cannot hold the minimum and is dropped. The bound is the smallest enclosure of the boxes
left — valid whenever the search stops: on deciding (bound ``> 1``, or a centre ``≤ 1`` found,
so this sample cannot decide), or at its box budget (evaluations, so the result does not depend
on the machine's speed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from otmm_qp.reference.chain import Chain, chain_of
from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.robots.robot import FloatArray

#: Boxes halved per round (the ones with the smallest enclosure).
BATCH = 2048
#: Room [m or rad] taken off every enclosure against rounding.
ROUNDING = 1e-9


@dataclass(frozen=True)
class SampleBound:
    """A certified bound of one sample.

    Attributes:
        sample: ``k``.
        merit: ``min_{q ∈ B_k} m_k(q) ≥ merit`` [tolerances].
        found: Smallest ``m_k`` at an evaluated configuration (an upper bound of the minimum).
        boxes: Boxes evaluated.
    """

    sample: int
    merit: float
    found: float
    boxes: int


class SampleSearch:
    """The per-sample branch and bound of a problem (the module docstring)."""

    def __init__(self, problem: TrackingProblem) -> None:
        self.problem = problem
        self.chain: Chain = chain_of(problem.robot)
        columns = self.chain.columns
        self.lower = problem.lower[columns]
        self.upper = problem.upper[columns]
        self.step = problem.step[columns]
        self.q0 = problem.q0[columns]
        self.revolute = ~self.chain.prismatic
        self.use_box(*self._box(problem.samples - 1))
        settings = problem.settings
        self.position_scale = (
            1.0 / settings.position_tolerance if settings.position_tolerance is not None else 0.0
        )
        self.rotation_scale = (
            1.0 / settings.orientation_tolerance
            if problem.pose and settings.orientation_tolerance is not None
            else 0.0
        )

    def use_box(self, lower: FloatArray, upper: FloatArray) -> None:
        """Levers ``λ`` and curvature ``λ_{max(i,j)}`` valid on every box in ``[lower, upper]``."""
        self.levers = self.chain.levers(lower, upper)
        size = self.chain.size
        self.curvature = self.levers[np.maximum.outer(np.arange(size), np.arange(size))]

    def _box(self, sample: int) -> tuple[FloatArray, FloatArray]:
        """``B_k`` in chain coordinates (a revolute range wider than 2π: a circle)."""
        finite = np.isfinite(self.step)
        reach = np.where(finite, sample * np.where(finite, self.step, 0.0), math.inf)
        lower = np.maximum(self.lower, self.q0 - reach)
        upper = np.minimum(self.upper, self.q0 + reach)
        centre = np.where(np.isfinite(lower) & np.isfinite(upper), 0.5 * (lower + upper), self.q0)
        circle = ~self.chain.prismatic & ~(upper - lower < 2.0 * math.pi)
        lower = np.where(circle, centre - math.pi, lower)
        upper = np.where(circle, centre + math.pi, upper)
        return lower, upper

    def _target(self, sample: int) -> tuple[FloatArray, FloatArray | None]:
        target = np.asarray(self.problem.targets[sample], dtype=float)
        if target.ndim == 2:
            return target[:3, 3], target[:3, :3]
        padded = np.zeros(3)
        padded[: target.size] = target
        return padded, None

    def evaluate(
        self, sample: int, centres: FloatArray, halves: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Centre merits ``(M,)``, enclosures ``(M,)`` and per-coordinate shares ``(M, m)``."""
        position, rotation = self._target(sample)
        p, frames, origins, omegas = self.chain.forward(centres)
        dim = self.chain.dim
        error = np.linalg.norm(p[:, :dim] - position[:dim], axis=1)
        jacobian = self.chain.jacobian(p, origins, omegas)[:, :, :dim]
        columns = np.linalg.norm(jacobian, axis=2)
        chord = np.where(self.revolute, np.minimum(halves, 2.0), halves)
        first = error - chord @ self.levers
        curvature = 0.5 * np.einsum("mi,ij,mj->m", halves, self.curvature, halves)
        second = error - np.sum(columns * halves, axis=1) - curvature
        # along the error's direction u: ‖e(q)‖ ≥ u·e(q) ≥ ‖e(c)‖ − Σ|u·J_i| h_i − curvature
        direction = (p[:, :dim] - position[:dim]) / np.maximum(error, 1e-300)[:, None]
        along = np.abs(np.einsum("mjd,md->mj", jacobian, direction))
        third = error - np.sum(along * halves, axis=1) - curvature
        position_low = np.maximum(np.maximum.reduce([first, second, third]) - ROUNDING, 0.0)
        merit = error * self.position_scale
        low = position_low * self.position_scale
        bending = halves * (halves @ self.curvature)  # each coordinate's part of the curvature
        share = (along * halves + bending) * self.position_scale
        if rotation is not None and self.rotation_scale > 0.0:
            angle = _angles(rotation, frames)
            turn = np.where(self.revolute, np.minimum(halves, math.pi), 0.0)
            axes_low, axes_share = self._axes(rotation, frames, omegas, halves)
            rotation_low = np.maximum(angle - np.sum(turn, axis=1), axes_low) - ROUNDING
            merit = np.maximum(merit, angle * self.rotation_scale)
            low = np.maximum(low, np.maximum(rotation_low, 0.0) * self.rotation_scale)
            share = share + axes_share * self.rotation_scale
        return merit, low, share

    def _axes(
        self, target: FloatArray, frames: FloatArray, omegas: FloatArray, halves: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        r"""The tool-axis bound of the angle ``(M,)`` [rad] and its per-coordinate shares.

        For a tool axis ``a``, ``v(q) = R(q) a`` has ``∂v/∂q_i = ω_i × v`` and
        ``‖∂²v/∂q_i∂q_j‖ = ‖ω_i × (ω_j × v)‖ ≤ 1`` (revolute; prismatic: 0), so along
        ``u = (v(c) − v*)/‖v(c) − v*‖``:
        ``‖v(q) − v*‖ ≥ ‖v(c) − v*‖ − Σ_i |u·(ω_i × v(c))| h_i − ½ (Σ_{revolute} h_i)²``, and
        the angle between ``R(q)`` and ``R*`` is at least ``2 arcsin(‖v(q) − v*‖/2)``
        (rotating by ``θ`` moves a unit vector by an angle ``≤ θ``); the largest over the
        three axes.
        """
        turning = np.where(self.revolute, halves, 0.0)
        curvature = 0.5 * np.sum(turning, axis=1) ** 2
        best = np.full(halves.shape[0], -math.inf)
        share = np.zeros(halves.shape)
        for axis in range(3):
            v = frames[:, :, axis]
            gap = v - target[None, :, axis]
            norm = np.linalg.norm(gap, axis=1)
            direction = gap / np.maximum(norm, 1e-300)[:, None]
            moves = np.cross(omegas, v[:, None, :])  # (M, m, 3)
            along = np.abs(np.einsum("mjd,md->mj", moves, direction)) * self.revolute
            chord = norm - np.sum(along * halves, axis=1) - curvature
            better = chord > best
            best = np.where(better, chord, best)
            part = along * halves + turning * np.sum(turning, axis=1)[:, None]
            share = np.where(better[:, None], part, share)
        return 2.0 * np.arcsin(np.clip(0.5 * best, 0.0, 1.0)), share

    def bound(self, sample: int, budget: int, goal: float = 1.0) -> SampleBound:
        """Lower bound of ``min_{B_k} m_k`` [tolerances], refined until it decides ``goal``.

        Stops when the bound exceeds ``goal``, when a centre at or below ``goal`` is found
        (the sample cannot certify ``goal``), or after ``budget`` boxes.
        """
        lower, upper = self._box(sample)
        centres = (0.5 * (lower + upper))[None, :]
        halves = (0.5 * (upper - lower))[None, :]
        merit, low, share = self.evaluate(sample, centres, halves)
        found = float(merit[0])
        boxes = 1
        while boxes < budget and found > goal and float(np.min(low)) <= goal:
            order = np.argsort(low)
            pick, rest = order[:BATCH], order[BATCH:]
            axis = np.argmax(share[pick], axis=1)
            rows = np.arange(pick.size)
            half = halves[pick].copy()
            half[rows, axis] *= 0.5
            left, right = centres[pick].copy(), centres[pick].copy()
            left[rows, axis] -= half[rows, axis]
            right[rows, axis] += half[rows, axis]
            new_centres = np.vstack([left, right])
            new_halves = np.vstack([half, half])
            new_merit, new_low, new_share = self.evaluate(sample, new_centres, new_halves)
            parent = np.concatenate([low[pick], low[pick]])
            new_low = np.maximum(new_low, parent)  # a child's minimum is at least its parent's
            boxes += new_centres.shape[0]
            found = min(found, float(np.min(new_merit)))
            centres = np.vstack([centres[rest], new_centres])
            halves = np.vstack([halves[rest], new_halves])
            low = np.concatenate([low[rest], new_low])
            share = np.vstack([share[rest], new_share])
            alive = low < found  # a box above the best centre cannot hold the minimum
            centres, halves, low, share = centres[alive], halves[alive], low[alive], share[alive]
            if low.size == 0:  # every box's enclosure is at or above the best centre
                return SampleBound(sample, inward(found), found, boxes)
        return SampleBound(sample, inward(min(float(np.min(low)), found)), found, boxes)


def inward(value: float) -> float:
    """``value`` less ``ROUNDING`` (relative and absolute), at least 0."""
    return max(value * (1.0 - ROUNDING) - ROUNDING, 0.0)


def _angles(target: FloatArray, frames: FloatArray) -> FloatArray:
    """Geodesic distances ``‖log₃(R* Rᵀ)‖`` [rad] of ``(M, 3, 3)`` rotations from ``R*``."""
    relative = target[None, :, :] @ np.transpose(frames, (0, 2, 1))
    trace = np.trace(relative, axis1=1, axis2=2)
    skew = np.stack(
        [
            relative[:, 2, 1] - relative[:, 1, 2],
            relative[:, 0, 2] - relative[:, 2, 0],
            relative[:, 1, 0] - relative[:, 0, 1],
        ],
        axis=1,
    )
    return np.arctan2(0.5 * np.linalg.norm(skew, axis=1), 0.5 * (trace - 1.0))
