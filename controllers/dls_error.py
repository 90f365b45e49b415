r"""Error-dependent damping (Sugihara 2011): the damped least squares of Levenberg–Marquardt IK."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.backends.backend import Backend, BackendOutput
from otmm_qp.exceptions import DimensionError, ParameterError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.validation import ArrayOf, Constraints, Interval, check_params

from .damping import damped_least_squares

#: The parameters renamed because they are λ² while ``damping`` means λ everywhere else.
RENAMED = {
    "damping_floor": (
        "renamed to lambda_sq_floor, the same number (it is λ² [task units²/rad²]; "
        "a damping factor λ gives lambda_sq_floor: λ²)"
    ),
    "max_damping": (
        "renamed to max_lambda_sq, the same number (it is λ² [task units²/rad²]; "
        "a cap λ_max gives max_lambda_sq: λ_max²)"
    ),
}

_NON_NEGATIVE = Interval(Real, 0, None, closed="left")
_POSITIVE = Interval(Real, 0, None, closed="neither")


class ErrorDampedLeastSquaresBackend(Backend):
    r"""DLS whose damping grows with the task error and shrinks to a floor as the error vanishes.

    Sugihara, "Solvability-unconcerned inverse kinematics by the Levenberg–Marquardt method",
    IEEE T-RO 27(5), 2011: each LM step solves
    :math:`(J^\top W_E J + W_N)\,\Delta q = J^\top W_E e` with
    :math:`W_N = E\,I + \bar W_N`, :math:`E = \tfrac12 e^\top W_E e`. With the task metric
    :math:`W_E` carried by the experiment's ``task_weight`` (the state's :math:`J_w = WJ`),
    this is DLS with the damping

    .. math::
        \lambda^2(e) = e^\top \mathrm{diag}(w_E)\,e + \bar w_N,\qquad
        \dot q = J_w^\top\big(J_wJ_w^\top + \lambda^2(e)\,I\big)^{-1}\dot x_w

    (the factor ½ of Sugihara's :math:`E` is absorbed in :math:`w_E`). So
    :math:`\lambda^2 \to \bar w_N` as :math:`e \to 0`: the step is (nearly) the pseudoinverse
    when the target is almost met, and heavily damped when it is far or unreachable — the
    field's standard answer to chatter beyond the reach.

    **Which error.** The backend sees the (weighted, filtered) command :math:`\dot x_w`, not
    the loop's tracking error, so the task error is read from it over a horizon τ [s]:
    :math:`e = \tau\,\dot x_w`.

    * ``error_horizon: null`` (default, τ = dt): *the LM step reading*. In the ``newton`` loop
      mode :math:`\dot x_c\,dt = x_d(t_{k+1}) - x_k` is exactly Sugihara's residual of the
      step; in ``clik`` it is :math:`(\dot x_d + K e_k)\,dt`.
    * ``error_horizon: 1/K`` (e.g. 0.1 s for K = 10 /s): *the set-point reading*. For a held
      target (:math:`\dot x_d = 0`) in ``clik``, :math:`\dot x_c/K = x_d - x_k`, the tracking
      error itself.

    Args:
        error_weight: :math:`w_E` ≥ 0, a scalar or one per task row, shape ``(n,)``
            [1/(task unit)² × (task unit/rad)², so λ² is in the units of σ²].
        lambda_sq_floor: :math:`\bar w_N = \lambda^2_{floor}` ≥ 0 [task units²/rad²], the
            damping at zero error (Sugihara's bias; ~1e-3 of the squared σ_max keeps exactly
            singular steps finite). Formerly ``damping_floor`` (the same number).
        error_horizon: τ > 0 [s] of :math:`e = \tau\dot x_w`; ``None``: the control period dt.
        max_lambda_sq: Upper bound of λ² > 0 [task units²/rad²] (``None``: none), so a huge
            error cannot freeze the arm. Formerly ``max_damping`` (the same number).

    The old names ``damping_floor`` / ``max_damping`` are refused in a config with their new
    name (:data:`RENAMED`, ``removed_parameters``).

    Raises:
        ParameterError: A value out of range, or ``max_lambda_sq < lambda_sq_floor``.
    """

    name = "dls_error"
    parameter_constraints: ClassVar[Constraints] = {
        "error_weight": ArrayOf(_NON_NEGATIVE, scalar=True, per="task row"),
        "lambda_sq_floor": _NON_NEGATIVE,
        "error_horizon": [Interval(Real, 0, None, closed="neither", unit="s"), None],
        "max_lambda_sq": [_POSITIVE, None],
    }
    removed_parameters: ClassVar[Mapping[str, str]] = RENAMED

    def __init__(
        self,
        error_weight: float | Sequence[float] = 1.0,
        lambda_sq_floor: float = 1e-3,
        error_horizon: float | None = None,
        max_lambda_sq: float | None = None,
    ) -> None:
        check_params(self, locals())
        self._per_row = not isinstance(error_weight, int | float)
        self.error_weight = np.atleast_1d(np.asarray(error_weight, dtype=float))
        self.lambda_sq_floor = float(lambda_sq_floor)
        self.error_horizon = None if error_horizon is None else float(error_horizon)
        self.max_lambda_sq = None if max_lambda_sq is None else float(max_lambda_sq)
        if self.max_lambda_sq is not None and self.max_lambda_sq < self.lambda_sq_floor:
            raise ParameterError(
                "max_lambda_sq",
                f"must be >= lambda_sq_floor ({self.lambda_sq_floor:g}), "
                f"got {self.max_lambda_sq:g}",
            )

    def bind(self, robot: Robot, dt: float) -> None:
        """Check the length of a per-row ``error_weight`` against the task dimension."""
        if self._per_row and self.error_weight.size != robot.task_dim:
            raise DimensionError("error_weight", (robot.task_dim,), self.error_weight.shape)
        super().bind(robot, dt)

    def damping_for(self, xdot: FloatArray) -> float:
        r"""λ² [task units²/rad²] for the command ``xdot`` (n,): :math:`e^\top W_E e + \bar w_N`."""
        horizon = self.dt if self.error_horizon is None else self.error_horizon
        error = horizon * np.asarray(xdot, dtype=float)
        with np.errstate(over="ignore", invalid="ignore"):
            mu = float(error @ (self.error_weight * error)) + self.lambda_sq_floor
        if not math.isfinite(mu):  # an overflowing command: damp as much as allowed
            mu = math.inf
        if self.max_lambda_sq is not None:
            mu = min(mu, self.max_lambda_sq)
        return mu

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Error-damped solution [rad/s], shape ``(nv,)``; ``damping`` is λ."""
        mu = self.damping_for(xdot)
        if not math.isfinite(mu):
            return self.unconstrained_output(np.zeros(state.Vt.shape[1]), math.inf)
        return self.unconstrained_output(damped_least_squares(state, xdot, mu), math.sqrt(mu))
