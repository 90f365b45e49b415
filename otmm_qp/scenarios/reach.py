r"""The arm's true reach from its model: the farthest the frame gets from the first joint.

.. math:: R = \max_{l \le q \le u} \|p(q) - b\|

(``b`` the first joint's origin, see :func:`~otmm_qp.scenarios.search.base_position``). Found by
sampling the joint box (deterministic seed) and refining the best samples by projected
gradient ascent on ``½‖p − b‖²`` (gradient ``J_pᵀ(p − b)``) with a backtracking step. A
local method: ``R`` is a lower bound of the maximum that the refinement makes tight in
practice (exact for planar arms, whose maximum is the stretched arm).

Unlike a sum of link offsets, this respects the joint limits and the geometry (the UR5 and
Panda reach about 0.95 m, their offset sums are 1.24 m and 1.09 m). The reach is about the
point ``b`` — what makes a target at ``ρR`` from ``b``, ``ρ > 1``, unreachable; the
distance from the first joint's *axis* is never larger.
"""

from __future__ import annotations

import weakref

import numpy as np

from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.scenarios.search import base_position, position_of, random_coordinates, sampling_bounds

#: Joint-box samples and how many of the best are refined.
SAMPLES = 600
REFINED = 6
#: Ascent iterations per refined sample.
ASCENT_ITERATIONS = 200

_cache: weakref.WeakKeyDictionary[Robot, float] = weakref.WeakKeyDictionary()


def _distance(robot: Robot, q: FloatArray, base: FloatArray) -> tuple[float, FloatArray]:
    """``‖p(q) − b‖`` [m] and its gradient of ``½‖p − b‖²``, shape ``(nv,)``."""
    x, jacobian = robot.kinematics(robot.configuration(q))
    offset = position_of(x) - base
    rows = offset.size
    return float(np.linalg.norm(offset)), jacobian[:rows].T @ offset


def _ascend(robot: Robot, q: FloatArray, base: FloatArray) -> float:
    """Projected gradient ascent with backtracking from ``q``; the distance reached [m]."""
    lower, upper = sampling_bounds(robot)
    value, gradient = _distance(robot, q, base)
    step = 1.0
    for _ in range(ASCENT_ITERATIONS):
        trial = np.clip(q + step * gradient, lower, upper)
        trial_value, trial_gradient = _distance(robot, trial, base)
        if trial_value > value + 1e-15:
            q, value, gradient = trial, trial_value, trial_gradient
            step *= 2.0
        else:
            step *= 0.25
            if step < 1e-12:
                break
    return value


def true_reach(robot: Robot) -> float:
    """The largest distance of the frame from the first joint's origin over the limits [m].

    Cached per robot object; deterministic.
    """
    if robot not in _cache:
        rng = np.random.default_rng(20260)
        base = base_position(robot)
        samples = [random_coordinates(robot, rng, 0.0) for _ in range(SAMPLES)]
        distances = np.array([_distance(robot, q, base)[0] for q in samples])
        best = np.argsort(distances)[::-1][:REFINED]
        _cache[robot] = max(_ascend(robot, samples[i], base) for i in best)
    return _cache[robot]
