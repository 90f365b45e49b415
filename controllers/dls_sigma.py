"""Damped least squares with damping driven by the smallest singular value."""

from __future__ import annotations

from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.backends.backend import Backend, BackendOutput
from otmm_qp.robots.robot import FloatArray
from otmm_qp.state import KinematicState
from otmm_qp.validation import Constraints, Interval, check_params

from .damping import damped_least_squares


class SigmaDampedLeastSquaresBackend(Backend):
    r"""Chiaverini / Maciejewski–Klein variable damping.

    .. math::
        \lambda^2 = \begin{cases}\lambda_{max}^2\,(1 - (\sigma_{min}/\varepsilon)^2) &
        \sigma_{min} < \varepsilon\\ 0 & \text{otherwise}\end{cases},\qquad
        \dot q = J^\top(JJ^\top + \lambda^2 I)^{-1}\dot x

    ``BackendOutput.damping`` is λ; status ``saturated`` when ``q̇`` exceeds the robot's
    joint speed limits.

    Args:
        lambda_max: Largest damping factor λ_max > 0 [task units].
        epsilon: Singular region width ε > 0 [task units].
    """

    name = "dls_sigma"
    parameter_constraints: ClassVar[Constraints] = {
        "lambda_max": Interval(Real, 0, None, closed="neither"),
        "epsilon": Interval(Real, 0, None, closed="neither"),
    }

    def __init__(self, lambda_max: float = 0.05, epsilon: float = 0.05) -> None:
        check_params(self, locals())
        self.lambda_max = float(lambda_max)
        self.epsilon = float(epsilon)

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Variably damped solution [rad/s], shape ``(nv,)``."""
        sigma_min = state.sigma_min
        mu = 0.0
        if sigma_min < self.epsilon:
            mu = self.lambda_max**2 * (1.0 - (sigma_min / self.epsilon) ** 2)
        return self.unconstrained_output(damped_least_squares(state, xdot, mu), float(np.sqrt(mu)))
