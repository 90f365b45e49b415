"""Adaptive damped least squares on the manipulability measure (the paper's SRI baseline)."""

from __future__ import annotations

from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.backends.backend import Backend, BackendOutput, svd_work
from otmm_qp.exceptions import ConfigError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.validation import Constraints, Interval, check_params

from .damping import damped_least_squares


class AdaptiveDampedLeastSquaresBackend(Backend):
    r"""Singularity-robust inverse with manipulability-driven damping.

    Nakamura–Hanafusa (1986), as used by Liu et al. and by the paper's Fig. 3:

    .. math::
        w = \sqrt{\det(JJ^\top)} = \prod_i \sigma_i,\qquad
        k = \begin{cases}\alpha\,(1 - w/w_0)^2 & w < w_0\\ 0 & \text{otherwise}\end{cases},\qquad
        \dot q = J^\top(JJ^\top + k I)^{-1}\dot x

    ``k`` is added to :math:`JJ^\top` directly (paper eq. 6 with α → k), so the damping
    factor reported in ``BackendOutput.damping`` is :math:`\lambda = \sqrt{k}` [task units].
    Status ``saturated`` when ``q̇`` exceeds the robot's joint speed limits.

    Give exactly one of ``w0`` (a constant threshold on ``w``) or ``sigma_threshold``: then
    :math:`w_0 = \sigma_{th}\prod_{i<n}\sigma_i` is evaluated each step from the other
    singular values, i.e. ``w < w0`` exactly when ``σ_min < σ_th``. For the 2-link arm this
    is the paper's ``w0 = |det J|`` at ``σ_min = σ_th`` up to the slow change of σ_max.

    Args:
        alpha: Maximum damping α ≥ 0 [task units²] (paper: 0.003).
        w0: Manipulability threshold > 0.
        sigma_threshold: σ_min threshold > 0 from which ``w0`` is derived.
    """

    name = "dls_adaptive"
    _work: FloatArray | None = None  # svd_work buffers, allocated by bind
    parameter_constraints: ClassVar[Constraints] = {
        "alpha": Interval(Real, 0, None, closed="left"),
        "w0": [Interval(Real, 0, None, closed="neither"), None],
        "sigma_threshold": [Interval(Real, 0, None, closed="neither"), None],
    }

    def __init__(
        self, alpha: float = 0.003, w0: float | None = None, sigma_threshold: float | None = None
    ) -> None:
        check_params(self, locals())
        if (w0 is None) == (sigma_threshold is None):
            raise ConfigError("w0", "give exactly one of w0 or sigma_threshold")
        self.alpha = float(alpha)
        self.w0 = None if w0 is None else float(w0)
        self.sigma_threshold = None if sigma_threshold is None else float(sigma_threshold)

    def damping_for(self, state: KinematicState) -> float:
        """Damping ``k = λ²`` [task units²] added to ``JJᵀ`` at this state."""
        sigma = state.sigma
        if sigma.size < state.task_dim:
            return self.alpha
        w = float(np.prod(sigma))
        if self.w0 is not None:
            w0 = self.w0
        else:  # __init__ guarantees exactly one of the two
            w0 = float(self.sigma_threshold or 0.0) * float(np.prod(sigma[:-1]))
        if w >= w0 or w0 <= 0.0:
            return 0.0
        return self.alpha * (1.0 - w / w0) ** 2

    def bind(self, robot: Robot, dt: float) -> None:
        """Attach the robot; allocate the step's SVD buffers (:func:`svd_work`)."""
        super().bind(robot, dt)
        self._work = svd_work(robot)

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Adaptively damped solution [rad/s], shape ``(nv,)``."""
        k = self.damping_for(state)
        return self.unconstrained_output(
            damped_least_squares(state, xdot, k, self._work), float(np.sqrt(k))
        )
