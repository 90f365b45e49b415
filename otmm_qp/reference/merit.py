r"""The min-max merit of a path: per-sample, per-part merits and ``φ = max m + ε ℓ̄``.

For a task with parts ``p`` (position, and orientation on a pose task with an orientation
tolerance), each sample ``k = 1..N−1`` has the merit ``m_{k,p} = ‖e_{k,p}‖/tol_p``
[tolerances], and a path the merit function

.. math::
    \varphi(Q) = \max_{k,p} m_{k,p} + \varepsilon\,\bar\ell(Q),\qquad
    \bar\ell = \frac{1}{N-1}\sum_{k\ge1} \tfrac12 \|S e_k\|^2

(``ε`` = :data:`TIE_BREAK`: a small tie-break that keeps the samples that do not bind near
their own best). The min-max polish (:mod:`otmm_qp.reference.conic`) decreases ``φ``; the
trust-region driver (:mod:`otmm_qp.reference.trust_region`) accepts its steps on it.
"""

from __future__ import annotations

import math

import numpy as np

from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.reference.trust_region import Iterate
from otmm_qp.robots.robot import FloatArray

#: Weight ε of the mean least squares tie-break (merit units: squared tolerances).
TIE_BREAK = 1e-3


def merit_parts(problem: TrackingProblem) -> list[tuple[slice, float]]:
    """The parts ``(rows of the error, tolerance)``: position, then orientation on a pose task.

    A part is there when its tolerance is set (orientation: on pose tasks only).
    """
    settings = problem.settings
    parts: list[tuple[slice, float]] = []
    if settings.position_tolerance is not None:
        parts.append((slice(0, problem.linear), settings.position_tolerance))
    if problem.pose and settings.orientation_tolerance is not None:
        parts.append((slice(3, 6), settings.orientation_tolerance))
    return parts


class MinMaxMerit:
    """``m_{k,p}`` and ``φ`` of paths of one task (module docstring).

    Args:
        problem: The task; its tolerances set the parts (:func:`merit_parts`).
    """

    def __init__(self, problem: TrackingProblem) -> None:
        self.problem = problem
        self.parts = merit_parts(problem)

    def __call__(self, path: FloatArray) -> Iterate:
        """The path ``(N, nv)`` with its errors ``(N, n)``, merits ``(N−1, parts)`` and ``φ``."""
        errors = self.problem.errors(path)
        merits = self.merits(errors)
        return Iterate(path, errors, merits, self.phi(errors, merits))

    def merits(self, errors: FloatArray) -> FloatArray:
        """``m_{k,p}`` of samples ``1..N−1``, shape ``(N−1, max(1, parts))`` [tolerances]."""
        out = np.zeros((errors.shape[0] - 1, max(1, len(self.parts))))
        for p, (rows, tolerance) in enumerate(self.parts):
            out[:, p] = np.linalg.norm(errors[1:, rows], axis=1) / tolerance
        return out

    def phi(self, errors: FloatArray, merits: FloatArray) -> float:
        """``φ = max m + ε ℓ̄`` (``inf`` when not finite)."""
        scaled = errors[1:] * self.problem.scale
        mean = 0.5 * float(np.mean(np.sum(scaled * scaled, axis=1)))
        value = float(np.max(merits)) + TIE_BREAK * mean
        return value if math.isfinite(value) else math.inf
