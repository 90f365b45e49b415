r"""The limits every reference path keeps, and whether a known path (a controller's) keeps them.

A path ``Q = (q_0, …, q_{N−1})`` sampled at ``t_k = k dt`` keeps the reference's limits when it
starts at the task's ``q_0``, covers the whole horizon (``N = max(1, round(duration/dt))``
samples), is finite, stays inside the position limits ``l ≤ q_k ≤ u`` and moves every joint
by at most ``v_max dt`` per sample,

.. math:: |q_{k,i} - q_{k-1,i}| \le v_{max,i}\,dt\,(1 + \text{STEP\_SLACK}),

with ``v_max`` the robot's velocity limits capped by ``settings.speed_limit`` (the study's
``max_joint_speed`` under ``reference.speed_bound: criteria``). Such a path is a *candidate*
of the reference: the reference is never above it (upper bound and position optimum), so its
oracle-relative error is ``≥ 0`` by construction — and it is defined only for such paths
(``kept_limits`` in :mod:`otmm_qp.studies.rows`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from otmm_qp.reference.settings import ReferenceSettings
from otmm_qp.robots.robot import FloatArray, Robot

#: Relative slack on a candidate's joint steps (its ``q̇ dt`` after rounding) [-].
STEP_SLACK = 1e-9


def speed_cap(robot: Robot, settings: ReferenceSettings) -> FloatArray:
    """``v_max`` [rad/s or m/s], shape ``(nv,)``: the robot's limits capped by ``speed_limit``."""
    speed = np.asarray(robot.velocity_limits, dtype=float).copy()
    if settings.speed_limit is not None:
        speed = np.minimum(speed, settings.speed_limit)
    return speed


@dataclass(frozen=True)
class PathLimits:
    """The limits of one task's reference paths.

    Attributes:
        q0: Start joint coordinates ``(nv,)``.
        samples: ``N``, samples of the horizon.
        dt: Sample period [s].
        lower, upper: Position limits ``(nv,)`` [rad or m] (±inf: none).
        speed: ``v_max`` ``(nv,)`` [rad/s or m/s] (inf: none).
        task_dim: Task error size ``n`` of the robot.
    """

    q0: FloatArray
    samples: int
    dt: float
    lower: FloatArray
    upper: FloatArray
    speed: FloatArray
    task_dim: int

    @classmethod
    def of(
        cls,
        robot: Robot,
        settings: ReferenceSettings,
        q0: FloatArray,
        dt: float,
        duration: float,
    ) -> PathLimits:
        """The limits of a task on ``robot`` from ``q0`` over ``duration`` [s] at ``dt`` [s]."""
        lower, upper = robot.position_limits
        return cls(
            np.asarray(q0, dtype=float).copy(),
            max(1, int(round(duration / dt))),
            float(dt),
            np.asarray(lower, dtype=float),
            np.asarray(upper, dtype=float),
            speed_cap(robot, settings),
            robot.task_dim,
        )

    def keeps(self, path: FloatArray, errors: FloatArray) -> bool:
        """Whether ``path`` ``(N, nv)`` with its recorded ``errors`` ``(N, n)`` keeps them.

        See the module docstring; a path of another length (a run that stopped early), with
        a non-finite value or another start is not kept.
        """
        path = np.asarray(path, dtype=float)
        errors = np.asarray(errors, dtype=float)
        if path.shape != (self.samples, self.q0.size) or errors.shape != (
            self.samples,
            self.task_dim,
        ):
            return False
        if not (np.all(np.isfinite(path)) and np.all(np.isfinite(errors))):
            return False
        if not np.array_equal(path[0], self.q0):
            return False
        if np.any(path < self.lower) or np.any(path > self.upper):
            return False
        limit = self.speed * self.dt * (1.0 + STEP_SLACK)
        return bool(np.all(np.abs(np.diff(path, axis=0)) <= limit))
