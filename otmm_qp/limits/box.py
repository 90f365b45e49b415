r"""Composing box limits: intersection, priority relaxation and the conflict line, in one place.

The feasible set of a step's box limits is their intersection,

.. math:: lb = \max_k lower_k,\qquad ub = \min_k upper_k,

empty exactly when some ``lb_i > ub_i`` (e.g. a start outside the position limits farther than
``q̇_max·dt/g``). :class:`LimitBox` evaluates it every step into preallocated arrays (static
limits, e.g. the speed limit, once per run); :func:`relaxed` gives the box a non-raising
infeasibility policy clips into; :func:`conflict` names the joint whose boxes clash.

*Soft* limits (:attr:`Limit.soft`, the command's acceleration and jerk,
:mod:`otmm_qp.limits.command_limit`) never make the box empty: after the hard boxes are
intersected, each soft box (and its :meth:`Limit.secondary` boxes) is applied in order as
:func:`relaxed` applies a box — intersected when that leaves the box non-empty, else the box
shrinks per joint to its point nearest the soft box — so the position and speed limits (and
the stopping distance the soft limit asks the position limits to keep, :meth:`Limit.brake_with`)
come first. :attr:`LimitBox.softened` says whether a soft box was given up on the step.
"""

from __future__ import annotations

import operator
from collections.abc import Sequence

import numpy as np

from otmm_qp.limits.limit import Box, Limit
from otmm_qp.plants.declaration import PlantDeclaration
from otmm_qp.robots.robot import FloatArray, Robot

__all__ = ["LimitBox", "conflict", "intersect", "relaxed"]


def intersect(boxes: Sequence[Box], out: Box) -> Box:
    r"""``(max_k lower_k, min_k upper_k)`` [rad/s] into ``out`` (shapes ``(nv,)``).

    Args:
        boxes: At least one box.
        out: Where to write (may not alias a box other than the first).
    """
    first = boxes[0]
    if len(boxes) == 1:
        np.copyto(out.lower, first.lower)
        np.copyto(out.upper, first.upper)
        return out
    np.maximum(first.lower, boxes[1].lower, out=out.lower)
    np.minimum(first.upper, boxes[1].upper, out=out.upper)
    for box in boxes[2:]:
        np.maximum(out.lower, box.lower, out=out.lower)
        np.minimum(out.upper, box.upper, out=out.upper)
    return out


def soften(bounds: Box, soft: Box) -> bool:
    r"""Apply ``soft`` to the non-empty ``bounds`` in place, as :func:`relaxed`; whether it clashed.

    Per joint, ``bounds ← bounds ∩ soft`` when non-empty, else the point of ``bounds`` nearest
    to ``soft`` (the end of ``bounds`` on the side of ``soft``) [rad/s], shapes ``(nv,)``.
    """
    lower, upper = bounds
    new_lower, new_upper = np.maximum(lower, soft.lower), np.minimum(upper, soft.upper)
    clash = new_lower > new_upper
    if clash.any():
        nearest = np.clip(np.where(soft.upper < lower, soft.upper, soft.lower), lower, upper)
        new_lower = np.where(clash, nearest, new_lower)
        new_upper = np.where(clash, nearest, new_upper)
    np.copyto(lower, new_lower)
    np.copyto(upper, new_upper)
    return bool(clash.any())


def relaxed(boxes: Sequence[Box]) -> Box:
    r"""A non-empty box honouring ``boxes`` in the given (priority) order.

    Starting from the first box, each next box is intersected when the intersection is
    non-empty; otherwise the current box shrinks, per joint, to its point nearest to that box.
    A joint beyond its position limit (priority 1) thus moves back as fast as its speed limit
    (priority 0) allows, whatever its acceleration limit (priority 2).

    Returns:
        New arrays [rad/s], shapes ``(nv,)``, ``lower ≤ upper`` when the first box is non-empty.
    """
    lower, upper = boxes[0].lower.copy(), boxes[0].upper.copy()
    for lo, hi in boxes[1:]:
        new_lower, new_upper = np.maximum(lower, lo), np.minimum(upper, hi)
        clash = new_lower > new_upper
        nearest = np.clip(np.where(hi < lower, hi, lo), lower, upper)
        lower = np.where(clash, nearest, new_lower)
        upper = np.where(clash, nearest, new_upper)
    return Box(lower, upper)


def conflict(named: Sequence[tuple[str, Box]], bounds: Box, joint_names: Sequence[str]) -> str:
    """One line naming the joint whose boxes clash most, and each limit's box there.

    Args:
        named: ``(limit name, its box)`` per limit.
        bounds: Their intersection (:func:`intersect`).
        joint_names: Names of the joints, length ``nv`` (``#i`` when shorter).
    """
    i = int(np.argmax(bounds.lower - bounds.upper))
    joint = joint_names[i] if i < len(joint_names) else f"#{i}"
    parts = ", ".join(f"{name} box [{box.lower[i]:.6g}, {box.upper[i]:.6g}]" for name, box in named)
    return f"joint {joint!r}: {parts} do not intersect"


class LimitBox:
    r"""The intersection of a run's box limits, evaluated in place each step.

    :meth:`bind` binds every limit, evaluates the static ones (intersected once) and allocates
    one ``(2, nv)`` array per dynamic limit and :attr:`bounds` for the result, so
    :meth:`compute` allocates nothing. After :meth:`compute`, :attr:`parts` hold every limit's
    box of that step (read by :meth:`relaxed` and :meth:`conflict`; overwritten next step).

    Args:
        limits: The box limits, any order; kept sorted by :attr:`Limit.priority` (stable).

    Attributes:
        limits: The limits, by priority.
        bounds: ``[lb; ub]`` [rad/s] of the last step, shape ``(2, nv)``.
        lists: The same ``(lb, ub)`` as two lists of Python floats (set by :meth:`compute`;
            the scalar tests of a step's solution read them instead of converting again).
        static: The intersection of the static limits' boxes (set by :meth:`bind`).
        softened: Whether the last :meth:`compute` gave up a soft box (braking first).
    """

    def __init__(self, limits: Sequence[Limit]) -> None:
        self.limits: tuple[Limit, ...] = tuple(sorted(limits, key=operator.attrgetter("priority")))
        self.softened = False

    def bind(self, robot: Robot, dt: float) -> None:
        """Bind the limits, evaluate the static ones and allocate.

        Raises:
            DimensionError: A limit's per-joint parameter does not match ``robot.nv``.
        """
        nv = robot.nv
        inf = np.full(nv, np.inf)
        self.bounds: FloatArray = np.empty((2, nv))
        self.lists: tuple[list[float], list[float]] = ([], [])
        self._bounds = Box(self.bounds[0], self.bounds[1])
        theta, zero = np.zeros(nv), np.zeros(nv)
        parts: list[Box] = []
        for limit in self.limits:
            limit.bind(robot, dt)
            array = np.empty((2, nv))
            parts.append(Box(array[0], array[1]))
            if limit.static:
                limit.compute_box(theta, zero, parts[-1])
        self.parts: tuple[Box, ...] = tuple(parts)
        for limit in self.limits:
            if limit.braking is not None:
                for other in self.limits:
                    other.brake_with(limit.braking, limit.jerk_braking, limit.stop_box)
        static = [box for limit, box in zip(self.limits, parts, strict=True) if limit.static]
        combined = Box(-inf, inf.copy())
        if static:
            combined = intersect(static, Box(np.empty(nv), np.empty(nv)))
        self.static: Box = combined
        self._dynamic = tuple(
            (limit, box) for limit, box in zip(self.limits, parts, strict=True) if not limit.static
        )
        self._sources: tuple[Box, ...] = (combined,) + tuple(
            box for limit, box in self._dynamic if not limit.soft
        )
        self._soft = tuple(
            (limit, box)
            for limit, box in self._dynamic
            if limit.soft and getattr(limit, "active", True)
        )
        #: Whether a soft limit is among the limits.
        self.has_soft = bool(self._soft)

    def declare_plant(self, declaration: PlantDeclaration) -> None:
        """Hand the plant's declaration to every limit (before :meth:`bind`)."""
        for limit in self.limits:
            limit.declare_plant(declaration)

    def reset(self) -> None:
        """Forget the limits' per-step state (a new run)."""
        for limit in self.limits:
            limit.reset()

    def compute(self, theta: FloatArray, qdot_prev: FloatArray) -> bool:
        """Write this step's intersection into :attr:`bounds`; return whether it is empty.

        Args:
            theta: Joint coordinates [rad or m], shape ``(nv,)``.
            qdot_prev: Previous joint velocity [rad/s], shape ``(nv,)``.
        """
        for limit, box in self._dynamic:
            limit.compute_box(theta, qdot_prev, box)
        intersect(self._sources, self._bounds)
        lower, upper = self.bounds.tolist()
        # A scalar test: a third of the cost of NumPy's greater + any on arm-sized nv.
        empty = any(map(operator.gt, lower, upper))
        if self._soft:
            softened = False
            if not empty:
                for limit, box in self._soft:
                    for part in (box, *limit.secondary()):
                        softened |= soften(self._bounds, part)
                lower, upper = self.bounds.tolist()
            self.softened = softened
        self.lists = (lower, upper)
        return empty

    def relaxed(self) -> Box:
        """The last step's box relaxed by priority (:func:`relaxed`), soft boxes included."""
        return relaxed([part for limit, box in zip(self.limits, self.parts, strict=True)
                        for part in (box, *limit.secondary())])  # fmt: skip

    def conflict(self, joint_names: Sequence[str]) -> str:
        """One line naming the last step's clashing joint (:func:`conflict`)."""
        named = [(limit.name, box) for limit, box in zip(self.limits, self.parts, strict=True)]
        return conflict(named, self._bounds, joint_names)
