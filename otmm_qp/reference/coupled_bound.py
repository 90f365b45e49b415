r"""A certificate that no path meets every tolerance: forward propagation of the feasible sets.

Every path within the limits that meets the tolerances at every sample (``m_k ≤ 1``) has
``q_k`` in

.. math::
    R_0 = \{q_0\},\qquad
    R_k = \big((R_{k-1} \oplus [-s, s]) \cap [l, u]\big) \cap \{q : m_k(q) \le 1\},

``s = v_{max}\,dt\,(1 + 4\,\text{STEP\_SLACK}) + 10^{-12}`` per joint [rad or m], above the
step a candidate path may take (``v_max dt (1 + STEP_SLACK)``, :mod:`.limits`), so a
controller's path is covered too. ``R_k = ∅`` at any ``k``
certifies that no such path exists (the task is ``unachievable``); this is the *speed
coupling* the per-sample bound (:mod:`.sample_bound`, ``R_k`` without the ``R_{k-1}`` term)
leaves out.

**Representation**: ``R_k`` is over-approximated by a union of boxes in chain coordinates
(:mod:`.chain`; the other joints do not move the frame). Per sample: every box is widened by
``s`` and clipped to the joint box, then refined by bisection (the boxes with the loosest
enclosure first, along the coordinate with the largest share of it, :meth:`SampleSearch.
evaluate`); a box whose enclosure of ``m_k`` is above 1 is dropped. Past ``CAP`` boxes the
union is merged into ``CAP`` covering boxes (median splits of the centres, each group's hull),
so every set stays an over-approximation and the certificate stays valid.

**Budget**: boxes evaluated per sample and per task are counts, not seconds, so a stored
certificate reproduces on any machine; the propagation also stops once ``STALL`` samples in a
row span the whole speed box ``B_k`` (nothing coupled: the per-sample bound sees as much).
A propagation stopped by its budget, its stall or the horizon certifies nothing.

**Value**: all boxes dropped had an enclosure of at least ``L`` (the smallest of them, > 1);
the same propagation with any threshold ``g < L`` in place of 1 drops the same boxes, so
``min_paths max_k m_k ≥ L``: the certified lower bound (less rounding).

Position alone can certify (``m_k ≥ ‖e_pos‖/tol_pos``); on pose tasks the orientation term of
the enclosure only adds to it (``m_k`` is the larger of the two).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from otmm_qp.reference.bound import LowerBound
from otmm_qp.reference.chain import UnsupportedChain
from otmm_qp.reference.limits import STEP_SLACK
from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.reference.sample_bound import SampleSearch, inward
from otmm_qp.robots.robot import FloatArray

#: Boxes kept from one sample to the next (merged into covering boxes beyond it).
CAP = 16
#: Boxes evaluated per sample at most (the refinement of that sample's set).
SAMPLE_BOXES = 2048
#: Boxes evaluated per task at most (past it: no certificate).
TASK_BOXES = 60_000
#: Boxes bisected at once.
BATCH = 512
#: Samples in a row whose set spans the whole speed box ``B_k`` after which the propagation
#: stops (no coupling gained: the per-sample bound sees the same box).
STALL = 8
#: Relative and absolute room on the widening ``s`` (rounding of the candidate's steps).
WIDEN = 4.0 * STEP_SLACK


@dataclass(frozen=True)
class CoupledBound:
    """The outcome of one forward propagation.

    Attributes:
        sample: First sample ``k`` with ``R_k = ∅`` (None: no certificate).
        merit: ``min_paths max_k m_k ≥ merit`` [tolerances] when certified (0 otherwise).
        boxes: Boxes evaluated.
        reached: Last sample propagated.
    """

    sample: int | None
    merit: float
    boxes: int
    reached: int


class CoupledSearch:
    """The forward propagation of a problem (the module docstring).

    Raises:
        UnsupportedChain: The robot has no chain :mod:`.chain` reads, or a joint of the chain
            has no finite speed limit (the sets would not be bounded).
    """

    def __init__(self, problem: TrackingProblem) -> None:
        self.search = SampleSearch(problem)
        search = self.search
        if not np.all(np.isfinite(search.step)):
            raise UnsupportedChain("a joint of the chain has no speed limit")
        self.samples = problem.samples
        speed = problem.speed[search.chain.columns] * problem.dt
        self.widen = speed * (1.0 + WIDEN) + 1e-12
        reach = (self.samples - 1) * self.widen
        search.use_box(
            np.maximum(search.lower, search.q0 - reach), np.minimum(search.upper, search.q0 + reach)
        )

    def run(
        self,
        last: int | None = None,
        sample_boxes: int = SAMPLE_BOXES,
        task_boxes: int = TASK_BOXES,
        cap: int = CAP,
    ) -> CoupledBound:
        """Propagate ``R_k`` for ``k = 1..last`` (default: the horizon) until one is empty."""
        search = self.search
        last = self.samples - 1 if last is None else min(last, self.samples - 1)
        low_box = search.q0[None, :].copy()
        high_box = search.q0[None, :].copy()
        dropped = math.inf
        boxes = 0
        stalled = 0
        for sample in range(1, last + 1):
            low_box = np.maximum(low_box - self.widen, search.lower)
            high_box = np.minimum(high_box + self.widen, search.upper)
            if boxes + low_box.shape[0] > task_boxes:  # out of budget: no certificate
                return CoupledBound(None, 0.0, boxes, sample - 1)
            budget = min(sample_boxes, task_boxes - boxes)
            low_box, high_box, used, smallest = self._refine(sample, low_box, high_box, budget)
            boxes += used
            dropped = min(dropped, smallest)
            if low_box.shape[0] == 0:
                return CoupledBound(sample, inward(dropped), boxes, sample)
            stalled = stalled + 1 if self._spans(sample, low_box, high_box) else 0
            if stalled >= STALL:
                return CoupledBound(None, 0.0, boxes, sample)
            if low_box.shape[0] > cap:
                low_box, high_box = merge(low_box, high_box, cap)
        return CoupledBound(None, 0.0, boxes, last)

    def _spans(self, sample: int, low_box: FloatArray, high_box: FloatArray) -> bool:
        """Whether the boxes' hull is the whole ``[l, u] ∩ [q0 − k s, q0 + k s]``.

        A stop rule only: it never decides a certificate.
        """
        search = self.search
        reach = sample * self.widen
        low = np.maximum(search.lower, search.q0 - reach)
        high = np.minimum(search.upper, search.q0 + reach)
        room = 1e-9 * (1.0 + reach)  # the repeated widening rounds differently from k·s
        return bool(
            np.all(np.min(low_box, axis=0) <= low + room)
            and np.all(np.max(high_box, axis=0) >= high - room)
        )

    def _refine(
        self, sample: int, low_box: FloatArray, high_box: FloatArray, budget: int
    ) -> tuple[FloatArray, FloatArray, int, float]:
        """The boxes of ``R_k`` whose enclosure is ≤ 1, bisected within ``budget`` evaluations.

        Boxes are kept as corners, so two halves share their cut exactly; each is evaluated
        on a box a few ulps wider (:func:`_measure`), so no configuration falls between them.

        Returns:
            ``(lower corners, upper corners, boxes evaluated, smallest dropped enclosure)``.
        """
        low, share = self._evaluate(sample, low_box, high_box)
        used = low_box.shape[0]
        dropped = float(np.min(low[low > 1.0], initial=math.inf))
        alive = low <= 1.0
        low_box, high_box, low, share = low_box[alive], high_box[alive], low[alive], share[alive]
        while low_box.shape[0] > 0 and used + 2 <= budget:
            take = min(BATCH, (budget - used) // 2)
            order = np.argsort(-np.sum(share, axis=1), kind="stable")  # loosest first
            pick, rest = order[:take], order[take:]
            axis = np.argmax(share[pick], axis=1)
            rows = np.arange(pick.size)
            cut = 0.5 * (low_box[pick, axis] + high_box[pick, axis])
            left_high, right_low = high_box[pick].copy(), low_box[pick].copy()
            left_high[rows, axis] = cut
            right_low[rows, axis] = cut
            new_low_box = np.vstack([low_box[pick], right_low])
            new_high_box = np.vstack([left_high, high_box[pick]])
            new_low, new_share = self._evaluate(sample, new_low_box, new_high_box)
            used += new_low_box.shape[0]
            new_low = np.maximum(new_low, np.concatenate([low[pick], low[pick]]))
            dropped = min(dropped, float(np.min(new_low[new_low > 1.0], initial=math.inf)))
            keep = new_low <= 1.0
            low_box = np.vstack([low_box[rest], new_low_box[keep]])
            high_box = np.vstack([high_box[rest], new_high_box[keep]])
            low = np.concatenate([low[rest], new_low[keep]])
            share = np.vstack([share[rest], new_share[keep]])
        return low_box, high_box, used, dropped

    def _evaluate(
        self, sample: int, low_box: FloatArray, high_box: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """Enclosures ``(M,)`` of ``m_k`` and shares ``(M, m)`` on the boxes (a few ulps wider)."""
        centres, halves = _measure(low_box, high_box)
        _, low, share = self.search.evaluate(sample, centres, halves)
        return low, share


def _measure(low_box: FloatArray, high_box: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Centres and half-widths of boxes that hold ``[low, high]`` despite rounding."""
    centres = 0.5 * (low_box + high_box)
    halves = 0.5 * (high_box - low_box) * (1.0 + 1e-12) + 1e-13 * (1.0 + np.abs(centres))
    return centres, halves


def merge(low_box: FloatArray, high_box: FloatArray, cap: int) -> tuple[FloatArray, FloatArray]:
    """``cap`` boxes covering the union of ``(M, m)`` boxes (each the hull of a group).

    Groups: the group with the widest hull is split at the median of its centres along the
    coordinate where they spread most, until there are ``cap`` groups (or every group is one
    box).
    """
    count = low_box.shape[0]
    if count <= cap:
        return low_box, high_box
    centres = 0.5 * (low_box + high_box)
    groups = [np.arange(count)]
    widths = [float(np.max(np.max(high_box, axis=0) - np.min(low_box, axis=0)))]
    while len(groups) < cap:
        splittable = [i for i, g in enumerate(groups) if g.size > 1]
        if not splittable:
            break
        index = max(splittable, key=lambda i: widths[i])
        group = groups.pop(index)
        widths.pop(index)
        points = centres[group]
        axis = int(np.argmax(np.ptp(points, axis=0)))
        order = group[np.argsort(points[:, axis], kind="stable")]
        for part in (order[: order.size // 2], order[order.size // 2 :]):
            groups.append(part)
            widths.append(float(np.max(np.max(high_box[part], 0) - np.min(low_box[part], 0))))
    low = np.array([np.min(low_box[g], axis=0) for g in groups])
    high = np.array([np.max(high_box[g], axis=0) for g in groups])
    return low, high


def coupled_certificate(problem: TrackingProblem, bound: LowerBound) -> LowerBound:
    """``bound`` raised to the propagation's value at its empty sample (``coupled@k``).

    Unchanged when the propagation certifies nothing or the robot has no readable chain.
    """
    try:
        search = CoupledSearch(problem)
    except UnsupportedChain:
        return bound
    outcome = search.run()
    if outcome.sample is None:
        return bound
    return bound.raised(outcome.sample, outcome.merit, "coupled")
