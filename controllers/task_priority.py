r"""Singularity-robust task priority (Chiaverini 1997): the secondary in a damped null space."""

from __future__ import annotations

from collections.abc import Mapping
from numbers import Real
from typing import Any, ClassVar, Literal

import numpy as np

from otmm_qp.backends.backend import Backend, BackendOutput, rank_cutoff
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.validation import Constraints, Interval, OneOf, check_params

from .jparse import SECONDARY
from .secondary_tasks import SecondaryTask, secondary_task_from


def sigma_damping(sigma_min: float, max_damping: float, sigma_threshold: float) -> float:
    r"""Chiaverini's damping schedule :math:`\lambda^2` [task units²/rad²].

    .. math::
        \lambda^2 = \begin{cases}\lambda_{max}^2\big(1 - (\sigma_{min}/\epsilon)^2\big)
        & \sigma_{min} < \epsilon\\ 0 & \text{otherwise}\end{cases}

    Args:
        sigma_min: Smallest singular value of the weighted task Jacobian.
        max_damping: λ_max ≥ 0 [task units/rad].
        sigma_threshold: ε > 0 [task units/rad].
    """
    if sigma_min >= sigma_threshold:
        return 0.0
    return max_damping**2 * (1.0 - (sigma_min / sigma_threshold) ** 2)


class TaskPriorityBackend(Backend):
    r"""Primary task by damped least squares, a joint-space secondary through a damped null space.

    Chiaverini, "Singularity-robust task-priority redundancy resolution for real-time
    kinematic control of robot manipulators", IEEE T-RA 13(3), 1997. The secondary task's own
    solution :math:`\dot q_2` (a joint-space task, ``secondary``) is computed *independently*
    of the primary and only then projected, so a singular primary cannot make the secondary
    ill-conditioned (the algorithmic singularity of the Nakamura–Hanafusa form) and vice versa:

    .. math::
        \dot q = J_w^{\#\lambda}\dot x_w + N\,\dot q_2,\qquad
        J_w^{\#\lambda} = J_w^\top(J_wJ_w^\top + \lambda^2 I)^{-1}
        = \sum_i \frac{\sigma_i}{\sigma_i^2 + \lambda^2} v_i u_i^\top

    with λ² from :func:`sigma_damping` and the null-space projector

    * ``projector: damped`` (default): :math:`N = I - J_w^{\#\lambda}J_w
      = \sum_i \frac{\lambda^2}{\sigma_i^2+\lambda^2} v_iv_i^\top + (I - V V^\top)` — near a
      singularity the secondary may also act along the singular direction, where the damped
      primary gives up;
    * ``projector: exact``: :math:`N = I - J_w^+J_w = I - V_rV_r^\top` over the singular
      values above the rank cutoff (Chiaverini's projector with the exact pseudoinverse).

    Away from singularities (σ_min ≥ ε, λ = 0) both are the orthogonal projector onto
    :math:`\ker J_w`: the primary is met exactly, :math:`J_w\dot q = \dot x_w`, and the
    secondary's null-space part is unchanged, :math:`N\dot q = N\dot q_2`; if
    :math:`\dot q_2` is itself compatible with the primary (:math:`J_w\dot q_2 = \dot x_w`),
    then :math:`\dot q = \dot q_2`.
    At an exactly singular :math:`J_w` every term is finite: the gains are bounded by
    :math:`1/(2\lambda)` and :math:`\|N\| \le 1`.

    Args:
        secondary: ``{type: posture | joint_limits, ...}`` (see
            :mod:`otmm_qp_controllers.secondary_tasks`); default a posture task with gain 1 /s
            toward the middle of the limits.
        max_damping: λ_max ≥ 0 [task units/rad] (default 0.05).
        sigma_threshold: ε > 0 [task units/rad] below which damping starts (default 0.05).
        projector: ``damped`` or ``exact``.
    """

    name = "task_priority"
    parameter_constraints: ClassVar[Constraints] = {
        "secondary": [SECONDARY, None],
        "max_damping": Interval(Real, 0, None, closed="left"),
        "sigma_threshold": Interval(Real, 0, None, closed="neither"),
        "projector": OneOf("damped", "exact"),
    }

    def __init__(
        self,
        secondary: SecondaryTask | Mapping[str, Any] | None = None,
        max_damping: float = 0.05,
        sigma_threshold: float = 0.05,
        projector: Literal["damped", "exact"] = "damped",
    ) -> None:
        check_params(self, locals())
        task = secondary_task_from({"type": "posture"} if secondary is None else secondary)
        assert task is not None  # noqa: S101 - a mapping always gives a task
        self.secondary = task
        self.max_damping = float(max_damping)
        self.sigma_threshold = float(sigma_threshold)
        self.projector = projector

    def bind(self, robot: Robot, dt: float) -> None:
        """Bind the secondary task (dimension checks) and the robot."""
        self.secondary.bind(robot)
        super().bind(robot, dt)

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """``J^{#λ} ẋ_w + N q̇_2`` [rad/s], shape ``(nv,)``; ``damping`` is λ."""
        sigma, Vt = state.sigma, state.Vt
        mu = sigma_damping(state.sigma_min, self.max_damping, self.sigma_threshold)
        cutoff = rank_cutoff(sigma)
        if mu > 0.0:
            gains = sigma / (sigma * sigma + mu)
        else:
            gains = np.where(sigma > cutoff, 1.0 / np.where(sigma > cutoff, sigma, 1.0), 0.0)
        primary = Vt.T @ (gains * (xdot @ state.U))
        q2 = self.secondary.joint_velocity(self.robot, state)
        if self.projector == "damped" and mu > 0.0:
            kept = sigma * sigma / (sigma * sigma + mu)  # weight of v_i in J^{#λ}J
        else:
            kept = (sigma > cutoff).astype(float)
        null = q2 - Vt.T @ (kept * (Vt @ q2))
        return self.unconstrained_output(primary + null, float(np.sqrt(mu)))
