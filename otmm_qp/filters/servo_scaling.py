r"""MoveIt Servo's singularity velocity scaling, written from the algorithm's description."""

from __future__ import annotations

from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.exceptions import ParameterError
from otmm_qp.filters.task_filter import FilterOutput, FilterReport, TaskFilter
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.validation import Constraints, Interval, OneOf, check_params


class ServoScalingFilter(TaskFilter):
    r"""Scale the whole command down as the condition number of ``J_w`` grows.

    With :math:`\kappa = \sigma_{max}/\sigma_{min}` (∞ at a singularity):

    .. math::
        \dot x_m = s\,\dot x,\qquad
        s = \begin{cases} 1 & \kappa \le \kappa_{lo} \\
        1 - \dfrac{\kappa - \kappa_{lo}}{\kappa_{hs} - \kappa_{lo}} &
        \kappa_{lo} < \kappa < \kappa_{hs} \\ 0 & \kappa \ge \kappa_{hs} \end{cases}

    where ``(κ_lo, κ_hs) = (lower_threshold, hard_stop_threshold)`` when the command moves
    *toward* the singularity, and both are multiplied by ``leaving_factor`` (≥ 1: a wider
    band, so less slowing) when it moves *away*.

    Direction test (Servo's look-ahead): the weakest left singular vector :math:`u_n` has an
    arbitrary sign, so its sign is made consistent with the command,
    :math:`\hat u = \mathrm{sign}(u_n^\top\dot x)\,u_n`, and the arm is stepped along the
    matching right singular vector, :math:`q' = q \oplus \epsilon\,\mathrm{sign}(u_n^\top
    \dot x)\,v_n` (``J v_n = σ_n u_n``). The command moves toward the singularity when
    :math:`\kappa(q') > \kappa(q)`. Servo steps :math:`J^+ u_n/100`, whose length
    :math:`1/(100\sigma_n)` explodes at the singularity; a fixed joint step ``ε =
    lookahead`` [rad] is used instead. A command with no component along :math:`u_n` counts
    as leaving (as in Servo). The look-ahead needs the robot: :meth:`bind` attaches it.
    Unbound, every command is treated as approaching (the conservative, narrow band).

    Differences from MoveIt Servo's current rule (moveit2 ``moveit_servo/src/utils/common.cpp``,
    ``velocityScalingFactorForSingularity``), checked against its source:

    * Servo keeps ``κ_lo`` when leaving and widens only the top of the band, to
      ``κ_lo + (κ_hs − κ_lo)·leaving_factor``; the default ``rule: band`` multiplies both.
    * Servo halts (``s = 0``) at ``κ ≥ κ_hs`` in *both* directions — the wider leaving band
      only changes the slope below ``κ_hs``; ``band`` lets a leaving command move up to
      ``leaving_factor·κ_hs``.
    * Servo's look-ahead step is :math:`J^+u_n/100` (length :math:`1/(100\sigma_n)`); here a
      fixed joint step ``lookahead`` along :math:`v_n` (same direction, bounded length).
    * Servo uses the unweighted 6-D Jacobian; here the (weighted) task Jacobian.
    * Defaults agree: 17, 30, 2; a command with no component along :math:`u_n` counts as
      leaving in both.

    ``rule: moveit`` reproduces Servo's band and halt exactly (the look-ahead step stays).

    Args:
        lower_threshold: ``κ_lo ≥ 1`` where scaling starts (Servo default 17).
        hard_stop_threshold: ``κ_hs > κ_lo`` where the command stops (Servo default 30).
        leaving_factor: Threshold multiplier ``≥ 1`` when leaving (Servo's
            ``leaving_singularity_threshold_multiplier``, default 2).
        lookahead: Joint step ``ε > 0`` [rad] of the direction test.
        rule: ``band`` (both thresholds × leaving_factor) or ``moveit`` (Servo's rule).
    """

    name = "servo_scaling"
    parameter_constraints: ClassVar[Constraints] = {
        "lower_threshold": Interval(Real, 1, None, closed="left"),
        "hard_stop_threshold": Interval(Real, 1, None, closed="left"),
        "leaving_factor": Interval(Real, 1, None, closed="left"),
        "lookahead": Interval(Real, 0, None, closed="neither", unit="rad"),
        "rule": OneOf("band", "moveit"),
    }

    def __init__(
        self,
        lower_threshold: float = 17.0,
        hard_stop_threshold: float = 30.0,
        leaving_factor: float = 2.0,
        lookahead: float = 1e-3,
        rule: str = "band",
    ) -> None:
        check_params(self, locals())
        self.rule = rule
        if not hard_stop_threshold > lower_threshold:
            raise ParameterError(
                "hard_stop_threshold",
                f"must be finite and > lower_threshold ({lower_threshold}), "
                f"got {hard_stop_threshold}",
            )
        self.lower_threshold = float(lower_threshold)
        self.hard_stop_threshold = float(hard_stop_threshold)
        self.leaving_factor = float(leaving_factor)
        self.lookahead = float(lookahead)
        self.robot: Robot | None = None
        #: Whether the last command was judged to approach the singularity.
        self.approaching = True

    def bind(self, robot: Robot, dt: float) -> None:
        """Attach the robot used by the look-ahead (``dt`` [s] is unused)."""
        self.robot = robot

    @staticmethod
    def condition_number(sigma: FloatArray, task_dim: int) -> float:
        """``σ_max/σ_min`` [-]; inf when ``σ_min = 0`` or when ``nv < n``."""
        if sigma.size < task_dim or sigma.size == 0 or not sigma[-1] > 0.0:
            return float("inf")
        return float(sigma[0] / sigma[-1])

    def scale(self, kappa: float, approaching: bool) -> float:
        """Scale ``s ∈ [0, 1]`` at condition number ``kappa``."""
        if self.rule == "moveit":
            lower, hard_stop = self.lower_threshold, self.hard_stop_threshold
            if kappa >= hard_stop:
                return 0.0
            top = hard_stop
            if not approaching:
                top = lower + (hard_stop - lower) * self.leaving_factor
            return 1.0 if kappa <= lower else 1.0 - (kappa - lower) / (top - lower)
        factor = 1.0 if approaching else self.leaving_factor
        lower, hard_stop = self.lower_threshold * factor, self.hard_stop_threshold * factor
        if kappa <= lower:
            return 1.0
        if kappa >= hard_stop:
            return 0.0
        return 1.0 - (kappa - lower) / (hard_stop - lower)

    def is_approaching(self, state: KinematicState, xdot: FloatArray, kappa: float) -> bool:
        """Servo's look-ahead: does ``xdot`` push the condition number up?"""
        if self.robot is None:
            return True
        projection = float(state.U[:, -1] @ xdot)
        if projection == 0.0:
            return False
        step = np.sign(projection) * self.lookahead * state.Vt[-1]
        q_ahead = self.robot.integrate(state.q, step, 1.0)
        jacobian = self.robot.jacobian(q_ahead)
        sigma = np.asarray(
            np.linalg.svd(state.weight[:, None] * jacobian, compute_uv=False), dtype=float
        )
        return self.condition_number(sigma, state.task_dim) > kappa

    def apply(self, state: KinematicState, xdot: FloatArray) -> FilterOutput:
        """Scale the weighted command ``xdot`` (n,) by ``s``."""
        kappa = self.condition_number(state.sigma, state.task_dim)
        if kappa <= self.lower_threshold:  # below both bands: nothing to decide
            self.approaching = True
            return FilterOutput(xdot, FilterReport(False, state.sigma_min, 0.0, 0.0))
        self.approaching = self.is_approaching(state, xdot, kappa)
        s = self.scale(kappa, self.approaching)
        if s >= 1.0:
            return FilterOutput(xdot, FilterReport(False, state.sigma_min, 0.0, 0.0))
        removed = (1.0 - s) * float(np.linalg.norm(xdot))
        return FilterOutput(s * xdot, FilterReport(True, state.sigma_min, 1.0 - s, removed))
