r"""σ-floored Levenberg–Marquardt damping: otmm-qp's own strategy (issue 20)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from numbers import Real
from typing import ClassVar

from otmm_qp.backends.backend import Backend, BackendOutput
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.validation import Constraints, Interval, check_params

from .damping import damped_least_squares
from .dls_error import ErrorDampedLeastSquaresBackend
from .task_priority import sigma_damping

#: ``damping_floor`` was λ² while ``damping`` means λ everywhere else.
RENAMED = {
    "damping_floor": (
        "renamed to lambda_sq_floor, the same number (it is λ² [task units²/rad²]; "
        "a damping factor λ gives lambda_sq_floor: λ²)"
    ),
}
_ERROR_TERM = ErrorDampedLeastSquaresBackend.parameter_constraints


class SigmaLevenbergMarquardtBackend(Backend):
    r"""DLS whose damping is the sum of a singularity term and a bounded task-error term.

    Design (see ``docs/strategies.md``, "A strategy of our own"). Two failure modes meet near
    singularities, and each classical damping answers only one:

    * a *reachable* target passed close to a singular pose: the error is small, so Sugihara's
      error damping vanishes and the step is the pseudoinverse — its joint-speed peak is what
      the σ-driven damping of Chiaverini/Maciejewski removes;
    * a target *beyond the reach* (or one that needs the singular direction): σ_min is not
      small all the time, but the error stays large and the pseudoinverse chatters — what
      Sugihara's error damping quiets.

    So the damping is their sum, the error part capped so it cannot freeze the arm:

    .. math::
        \lambda^2 = \bar w_N + \lambda_\sigma^2(\sigma_{min})
        + \min\big(w_E\,\|\tau\dot x_w\|^2,\ \lambda_{e,max}^2\big),\qquad
        \dot q = J_w^\top(J_wJ_w^\top + \lambda^2 I)^{-1}\dot x_w

    with :math:`\lambda_\sigma^2` Chiaverini's schedule
    (:func:`~otmm_qp_controllers.task_priority.sigma_damping`) and the error read as in
    :class:`~otmm_qp_controllers.dls_error.ErrorDampedLeastSquaresBackend` (``error_horizon``
    τ, default dt). Away from singularities and on target, λ² = w̄_N (default 0): the exact
    pseudoinverse, no accuracy lost where none needs to be. It composes with an OTMM filter in
    front (the filter bounds the singular channel of the command, this backend its inverse).

    Args:
        error_weight: :math:`w_E` ≥ 0 (scalar or per row) of the error term.
        error_horizon: τ > 0 [s]; ``None``: dt.
        max_error_damping: :math:`\lambda_{e,max}` > 0 [task units/rad], cap of the error term.
        max_damping: :math:`\lambda_{max}` ≥ 0 [task units/rad] of the σ term.
        sigma_threshold: ε > 0 [task units/rad] below which the σ term starts.
        lambda_sq_floor: :math:`\bar w_N = \lambda^2_{floor}` ≥ 0 [task units²/rad²]
            (formerly ``damping_floor``, the same number).
    """

    name = "sigma_lm"
    parameter_constraints: ClassVar[Constraints] = {
        "error_weight": _ERROR_TERM["error_weight"],
        "error_horizon": _ERROR_TERM["error_horizon"],
        "max_error_damping": [Interval(Real, 0, None, closed="neither"), None],
        "max_damping": Interval(Real, 0, None, closed="left"),
        "sigma_threshold": Interval(Real, 0, None, closed="neither"),
        "lambda_sq_floor": Interval(Real, 0, None, closed="left"),
    }
    removed_parameters: ClassVar[Mapping[str, str]] = RENAMED

    def __init__(
        self,
        error_weight: float | Sequence[float] = 10.0,
        error_horizon: float | None = None,
        max_error_damping: float | None = None,
        max_damping: float = 0.05,
        sigma_threshold: float = 0.05,
        lambda_sq_floor: float = 0.0,
    ) -> None:
        check_params(self, locals())
        cap = None if max_error_damping is None else float(max_error_damping)
        self.error = ErrorDampedLeastSquaresBackend(
            error_weight=error_weight,
            lambda_sq_floor=0.0,
            error_horizon=error_horizon,
            max_lambda_sq=None if cap is None else cap**2,
        )
        self.max_error_damping = cap
        self.max_damping = float(max_damping)
        self.sigma_threshold = float(sigma_threshold)
        self.lambda_sq_floor = float(lambda_sq_floor)

    def bind(self, robot: Robot, dt: float) -> None:
        """Bind the error term (its per-row weight check) and the robot."""
        self.error.bind(robot, dt)
        super().bind(robot, dt)

    def damping_for(self, state: KinematicState, xdot: FloatArray) -> float:
        """λ² [task units²/rad²] of this step (see the class docstring)."""
        sigma_part = sigma_damping(state.sigma_min, self.max_damping, self.sigma_threshold)
        return self.lambda_sq_floor + sigma_part + self.error.damping_for(xdot)

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Damped solution [rad/s], shape ``(nv,)``; ``damping`` is λ."""
        mu = self.damping_for(state, xdot)
        return self.unconstrained_output(damped_least_squares(state, xdot, mu), math.sqrt(mu))
