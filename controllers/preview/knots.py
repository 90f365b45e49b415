r"""The horizon's knots: a few fine steps at ``dt``, then coarser ones (move blocking).

.. math::
    0 = \tau_0 < \tau_1 < \dots < \tau_K = H,\qquad h_i = \tau_i - \tau_{i-1},\qquad
    h_1 = \dots = h_f = dt,\quad h_{f+1} = \dots = h_K = \Delta

The joint velocity is held constant on each segment ``(τ_{i−1}, τ_i]`` (``v_i`` [rad/s]), so
``K`` knots carry a horizon of ``f·dt + (K − f)·Δ`` seconds: 4 fine steps and 36 coarse ones
of 0.1 s give 4 s at dt = 0.02 s. :meth:`KnotGrid.shift_matrix` maps a plan to the next step's
nominal (the plan advanced by ``dt``, re-anchored at the state the robot is in).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from otmm_qp.exceptions import ParameterError
from otmm_qp.robots.robot import FloatArray

__all__ = ["KnotGrid"]

#: Relative tolerance of "is a multiple of" tests on times [-].
_TOL = 1e-9
#: Most segments ``K`` a horizon may have (``knots`` and ``fine_steps`` are capped by it).
MAX_KNOTS = 10_000
#: Memory of the preview QP per entry of its dense ``(K·n)²`` matrices [bytes], about: the
#: Hessian, the task Hessian and two block copies (measured at bind: 32.5 bytes on the Panda
#: at K = 16 … 256), plus the solver's copy.
BYTES_PER_ENTRY = 40
#: Largest memory the preview QP may need [bytes] (checked before anything is allocated).
MAX_QP_BYTES = 256 * 2**20


def _multiple(value: float, unit: float) -> int | None:
    """``value / unit`` when it is an integer (within :data:`_TOL`), else None."""
    ratio = value / unit
    nearest = round(ratio)
    return int(nearest) if abs(ratio - nearest) <= _TOL * max(1.0, abs(ratio)) else None


def _size(count: float) -> str:
    """``count`` bytes as ``12 MiB`` / ``3.4 GiB`` / ``17.8 PiB``."""
    for unit in ("bytes", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if count < 1024 or unit == "PiB":
            return f"{count:.3g} {unit}"
        count /= 1024
    return f"{count:.3g} PiB"  # pragma: no cover - the loop returns at PiB


@dataclass(frozen=True)
class KnotGrid:
    r"""The segment lengths ``h_i`` [s] of a horizon, shape ``(K,)``.

    Attributes:
        steps: ``h_i > 0`` [s], shape ``(K,)``; the first is the control period ``dt``.
    """

    steps: FloatArray

    @classmethod
    def layout(
        cls,
        horizon: float,
        dt: float,
        fine_steps: int,
        knots: int,
        coarse_step: float | None = None,
    ) -> KnotGrid:
        r"""The grid of ``horizon`` [s] at control period ``dt`` [s].

        ``f = min(fine_steps, ⌊H/dt⌋)`` fine steps, then the rest ``R = H − f·dt`` in
        ``n_c`` equal coarse steps: ``n_c = R/Δ`` when ``coarse_step`` Δ is given (a multiple
        of ``dt`` dividing ``R``), else the most that fit ``knots`` with ``Δ ≥ dt``
        (``n_c = min(knots − f, max(1, ⌊R/dt⌋))``, ``Δ = R/n_c``).

        Raises:
            ParameterError: ``horizon`` shorter than ``dt``; ``coarse_step`` not a multiple of
                ``dt`` or not dividing the rest; more knots needed than the cap ``knots``.
        """
        if not (math.isfinite(horizon) and horizon > 0.0):
            raise ParameterError("horizon", f"must be a finite number > 0 [s], got {horizon}")
        whole = _multiple(horizon, dt)
        if horizon < dt and whole != 1:
            raise ParameterError(
                "horizon", f"{horizon:g} s is shorter than one control period dt = {dt:g} s"
            )
        fine = min(fine_steps, whole if whole is not None else int(math.floor(horizon / dt)))
        if fine > knots:
            raise ParameterError(
                "knots", f"{knots} is below the {fine} fine steps the window starts with"
            )
        rest = horizon - fine * dt
        coarse: list[float] = []
        if rest > _TOL * horizon:
            if knots - fine < 1:
                raise ParameterError(
                    "knots",
                    f"{knots} cannot reach the horizon: {fine} fine steps of dt = {dt:g} s "
                    f"cover {fine * dt:g} of {horizon:g} s and leave no coarse knot",
                )
            if coarse_step is not None:
                if _multiple(coarse_step, dt) is None:
                    raise ParameterError(
                        "coarse_step", f"{coarse_step:g} s is not a multiple of dt = {dt:g} s"
                    )
                count = _multiple(rest, coarse_step)
                if count is None:
                    raise ParameterError(
                        "coarse_step",
                        f"{coarse_step:g} s does not divide the horizon after the fine steps, "
                        f"{horizon:g} − {fine}·{dt:g} = {rest:g} s",
                    )
                if fine + count > knots:
                    raise ParameterError(
                        "knots",
                        f"{knots} is below the {fine + count} knots that coarse_step = "
                        f"{coarse_step:g} s needs to reach {horizon:g} s",
                    )
            else:
                count = min(knots - fine, max(1, int(math.floor(rest / dt + _TOL))))
            coarse = [rest / count] * count
        return cls(np.array([dt] * fine + coarse, dtype=float))

    @staticmethod
    def check_memory(count: int, joints: int) -> None:
        r"""Refuse a QP of ``count`` knots × ``joints`` needing more than :data:`MAX_QP_BYTES`.

        The memory is about :data:`BYTES_PER_ENTRY` · (K·n)² [bytes]; the work of a step grows
        as (K·n)³.

        Raises:
            ParameterError: Naming ``knots``, the memory needed and the bound.
        """
        variables = count * joints
        need = BYTES_PER_ENTRY * variables**2
        if need > MAX_QP_BYTES:
            most = int(math.isqrt(MAX_QP_BYTES // BYTES_PER_ENTRY) // max(joints, 1))
            raise ParameterError(
                "knots",
                f"{count} segments × {joints} joints need ~{_size(need)} for the QP, above "
                f"{_size(MAX_QP_BYTES)} (at most {most} segments on {joints} joints)",
            )

    @property
    def count(self) -> int:
        """Number of segments (= knots after ``τ_0``) ``K``."""
        return int(self.steps.shape[0])

    @property
    def taus(self) -> FloatArray:
        """Knot offsets ``τ_1 … τ_K`` [s], shape ``(K,)``."""
        return np.cumsum(self.steps)

    @property
    def horizon(self) -> float:
        """``H = τ_K`` [s]."""
        return float(self.steps.sum())

    def shift_matrix(self) -> FloatArray:
        r"""The linear map from a plan's velocities to the next step's nominal ones, ``(K, K)``.

        With the plan's displacement :math:`P(\tau) = \int_0^\tau v`, piecewise linear through
        :math:`P(\tau_i) = \sum_{j \le i} h_j v_j` and held after ``τ_K``, the nominal at the
        next step (time advanced by ``h_1 = dt``, re-anchored at the new state) is

        .. math:: \bar d_i = P(\tau_i + dt) - P(dt),\qquad
                  \bar v_i = (\bar d_i - \bar d_{i-1}) / h_i

        — linear in ``v``, so one matrix ``M`` with :math:`\bar v = M v` (per joint).
        """
        count, taus = self.count, self.taus
        knots = np.concatenate([[0.0], taus])
        shifted = np.minimum(np.concatenate([[0.0], taus]) + self.steps[0], knots[-1])
        matrix = np.empty((count, count))
        for j in range(count):
            velocity = np.zeros(count)
            velocity[j] = 1.0
            displacement = np.concatenate([[0.0], np.cumsum(self.steps * velocity)])
            moved = np.interp(shifted, knots, displacement)
            matrix[:, j] = np.diff(moved - moved[0]) / self.steps
        return matrix
