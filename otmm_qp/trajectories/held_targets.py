r"""Held targets: piecewise-constant set-points, each held for a stated time.

How teleoperation and many papers command an arm: the target jumps to a new value and stays
there, so the controller (not the trajectory) decides how to get there. With
:math:`T_i` the start of hold ``i`` (:math:`T_0 = 0`, :math:`T_{i+1} = T_i + h_i`):

.. math::
    x_d(t) = X_i,\qquad \dot x_d(t) = 0 \qquad \text{for } T_i \le t < T_{i+1}

and the last target is held after the end. In the ``clik`` loop mode the command is then the
pure feedback :math:`\dot x_c = K\,(X_i - x_k)`; in ``feedforward`` it is zero (the arm does
not move, by construction); in ``newton`` it is :math:`(X_i - x_k)/dt` — one step to the target.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.exceptions import ConfigError, DimensionError, ParameterError
from otmm_qp.robots.robot import FloatArray
from otmm_qp.trajectories.pose import rpy_matrix
from otmm_qp.trajectories.time_grid import piece_index, start_ticks
from otmm_qp.trajectories.trajectory import Trajectory
from otmm_qp.validation import ArrayOf, Constraints, InstanceOf, Interval


class HeldTargetsTrajectory(Trajectory):
    r"""Targets ``X_i`` held for ``h_i`` seconds each (see the module docstring).

    Args:
        start: Task value at the start configuration: a point ``(d,)`` or a pose ``(4, 4)``.
        targets: The set-points, in order: ``[x, y(, z)]`` [m] for position tasks; for pose
            tasks ``[x, y, z]`` (keep the previous orientation) or
            ``[x, y, z, roll, pitch, yaw]`` [m, rad].
        hold: Time each target is held [s]: one number for all, or one per target; > 0.
        initial_hold: Time [s] the start value is held before the first target (≥ 0).
    """

    name = "held_targets"
    #: Causal: each set-point is revealed when it is commanded, as in teleoperation
    #: (:attr:`Trajectory.lookahead`), so no controller may anticipate the next jump.
    lookahead = 0.0

    parameter_constraints: ClassVar[Constraints] = {
        "targets": InstanceOf(
            (list, tuple),
            "a list of targets [x, y(, z)] [m] (pose: + roll, pitch, yaw [rad])",
            exclude=(str,),
        ),
        "hold": ArrayOf(
            Interval(Real, 0, None, closed="neither", unit="s"), scalar=True, per="target"
        ),
        "initial_hold": Interval(Real, 0, None, unit="s"),
    }

    def __init__(
        self,
        start: FloatArray,
        targets: Sequence[Sequence[float]],
        hold: float | Sequence[float] = 1.0,
        initial_hold: float = 0.0,
    ) -> None:
        value = np.asarray(start, dtype=float)
        self.is_pose = value.shape == (4, 4)
        if not isinstance(targets, list | tuple) or len(targets) == 0:
            raise ConfigError("targets", "give at least one target, a list of [x, y(, z)]")
        holds = self._holds(hold, len(targets))
        if not (
            isinstance(initial_hold, int | float)
            and not isinstance(initial_hold, bool)
            and math.isfinite(initial_hold)
            and initial_hold >= 0.0
        ):
            raise ParameterError(
                "initial_hold", f"must be a finite number >= 0 [s], got {initial_hold!r:.40}"
            )
        values: list[FloatArray] = [value.copy()] if initial_hold > 0.0 else []
        durations: list[float] = [float(initial_hold)] if initial_hold > 0.0 else []
        previous = value.copy()
        dim = 3 if self.is_pose else value.size
        for j, raw in enumerate(targets):
            try:
                entry = np.asarray(raw, dtype=float)
            except (TypeError, ValueError):
                raise ParameterError(
                    f"targets.{j}", f"must be a list of numbers, got {raw!r:.40}"
                ) from None
            allowed = (3, 6) if self.is_pose else (dim,)
            if entry.ndim != 1 or entry.size not in allowed:
                raise DimensionError(f"targets.{j}", (allowed[-1],), entry.shape)
            if not np.all(np.isfinite(entry)):
                raise ParameterError(f"targets.{j}", "must be finite")
            if self.is_pose:
                pose = previous.copy()
                pose[:3, 3] = entry[:3]
                if entry.size == 6:
                    pose[:3, :3] = rpy_matrix(entry[3:6].tolist())
                target = pose
            else:
                target = entry.copy()
            values.append(target)
            durations.append(holds[j])
            previous = target
        self.targets = values
        self.starts = np.concatenate(([0.0], np.cumsum(durations)[:-1]))
        self._start_ticks = start_ticks(durations)  # the switch times, compared as integers
        self.duration = float(np.sum(durations))
        self._zero = np.zeros(6 if self.is_pose else dim)

    @staticmethod
    def _holds(hold: float | Sequence[float], count: int) -> list[float]:
        """Hold time of each target [s], validated."""
        if isinstance(hold, int | float) and not isinstance(hold, bool):
            values = [float(hold)] * count
        elif isinstance(hold, list | tuple):
            if len(hold) != count:
                raise DimensionError("hold", (count,), (len(hold),))
            values = []
            for v in hold:
                if isinstance(v, bool) or not isinstance(v, int | float):
                    raise ParameterError(
                        "hold", f"every hold time must be a number [s], got {v!r:.40}"
                    )
                values.append(float(v))
        else:
            raise ParameterError(
                "hold", f"must be a number or a list of numbers [s], got {hold!r:.40}"
            )
        if not all(math.isfinite(v) and v > 0.0 for v in values):
            raise ParameterError(
                "hold", f"every hold time must be a finite number > 0 [s], got {hold!r:.40}"
            )
        return values

    def index(self, t: float) -> int:
        """Index of the target held at ``t`` [s] (the first before 0, the last after the end).

        Switch times and ``t`` are compared in integer ticks (:mod:`.time_grid`): ``hold: 0.1``
        sampled at ``t_k = k·0.02`` switches at ``k = 5, 10, 15, …``, not a step late where the
        float sum of holds exceeds ``k·dt`` by an ulp.
        """
        return piece_index(self._start_ticks, t)

    def sample(self, t: float) -> tuple[FloatArray, FloatArray]:
        """Held target ``X_i`` and zero velocity at ``t`` [s]."""
        return self.targets[self.index(t)].copy(), self._zero.copy()
