r"""Weighted least-norm joint-limit avoidance (Chan & Dubey 1995)."""

from __future__ import annotations

import math
from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.backends.backend import Backend, BackendOutput, rank_cutoff
from otmm_qp.robots.robot import FloatArray
from otmm_qp.state import KinematicState, thin_svd
from otmm_qp.validation import Constraints, Interval, check_params


def limit_cost_gradient(theta: FloatArray, lower: FloatArray, upper: FloatArray) -> FloatArray:
    r"""Chan & Dubey's :math:`|\partial H/\partial\theta_i|`, shape ``(nv,)`` [1/rad].

    .. math::
        H(\theta) = \sum_i \frac{(\theta_{max,i} - \theta_{min,i})^2}
        {4(\theta_{max,i} - \theta_i)(\theta_i - \theta_{min,i})},\qquad
        \frac{\partial H}{\partial\theta_i} = \frac{(\theta_{max,i} - \theta_{min,i})^2
        (2\theta_i - \theta_{max,i} - \theta_{min,i})}
        {4(\theta_{max,i} - \theta_i)^2(\theta_i - \theta_{min,i})^2}

    H is 1 at the middle of a joint's range and infinite at its limits. Joints with an
    infinite limit get 0; a joint on or beyond a limit gets ``inf``.
    """
    span = upper - lower
    usable = np.isfinite(span) & (span > 0.0)
    up = np.where(usable, upper - theta, 1.0)
    down = np.where(usable, theta - lower, 1.0)
    outside = usable & ((up <= 0.0) | (down <= 0.0))
    safe_span = np.where(usable, span, 0.0)
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        value = np.abs(safe_span**2 * (up - down) / (4.0 * up**2 * down**2))
    value = np.where(usable, value, 0.0)
    return np.where(outside, np.inf, np.where(np.isfinite(value), value, np.inf))


class WeightedLeastNormBackend(Backend):
    r"""Weighted least-norm solution with joint weights from the limit-distance gradient.

    Chan & Dubey, "A weighted least-norm solution based scheme for avoiding joint limits for
    redundant joint manipulators", IEEE T-RA 11(2), 1995:

    .. math::
        \dot q = W^{-1}J_w^\top\big(J_wW^{-1}J_w^\top + \lambda^2 I\big)^{-1}\dot x_w,\qquad
        w_i = \begin{cases} 1 + |\partial H/\partial\theta_i| & \Delta|\partial H/\partial
        \theta_i| \ge 0 \ \text{(moving toward the limit)}\\
        1 & \Delta|\partial H/\partial\theta_i| < 0 \ \text{(moving away)}\end{cases}

    with :math:`|\partial H/\partial\theta|` of :func:`limit_cost_gradient`. The *moving
    away* rule releases a joint that is already leaving its limit, so it is not held back
    on its way out. :math:`\Delta` is the change since the previous step; on the first step
    of a run (no history) its sign is taken from :math:`\dot q_{prev}` (the first-order
    change, :math:`\mathrm{sign}(\partial H/\partial\theta_i)\,\dot q_{prev,i}`).

    Solved as :math:`\dot q = W^{-1/2}(J_wW^{-1/2})^{\#\lambda}\dot x_w` from the SVD of
    :math:`J_wW^{-1/2}`: a second, different matrix than the step's :math:`J_w`, so its SVD
    is computed here — only when some weight differs from 1; otherwise the shared SVD is used.
    A joint on or beyond its limit has :math:`w = \infty`, i.e. :math:`W^{-1/2}_{ii} = 0`, while
    its previous velocity points outward, else :math:`w = 1` so it can return. WLN shapes the
    motion, it does not enforce the limits: a discrete step can still cross one.

    λ = 0 (the paper) truncates singular values below the rank cutoff, so an exactly singular
    :math:`J_w` gives a finite step — but not a small one: when large weights make
    :math:`J_wW^{-1/2}` nearly singular (a target that needs a joint past its limit), the
    undamped WLN diverges (``tests/controllers/test_wln.py``: a 3-link arm ends 11.9 rad past a
    limit);
    λ = 0.05 stops it at the limit. Use λ > 0 on real arms.

    Args:
        damping: λ ≥ 0 [task units/rad] (default 0: the paper's undamped WLN).
    """

    name = "wln"
    parameter_constraints: ClassVar[Constraints] = {
        "damping": Interval(Real, 0, None, closed="left"),
    }

    def __init__(self, damping: float = 0.0) -> None:
        check_params(self, locals())
        self.damping = float(damping)
        self._previous: FloatArray | None = None

    def reset(self) -> None:
        """Forget the previous gradient (the "moving away" history)."""
        self._previous = None

    def weights(self, state: KinematicState, qdot_prev: FloatArray) -> FloatArray:
        """Joint weights ``w_i ∈ [1, ∞]``, shape ``(nv,)``, updating the gradient history."""
        lower, upper = (np.asarray(v, dtype=float) for v in self.robot.position_limits)
        theta = self.robot.joint_coordinates(state.q)
        gradient = limit_cost_gradient(theta, lower, upper)
        middle = 0.5 * (
            np.where(np.isfinite(lower), lower, 0.0) + np.where(np.isfinite(upper), upper, 0.0)
        )
        if self._previous is None:
            toward = np.sign(theta - middle) * qdot_prev >= 0.0
        else:
            with np.errstate(invalid="ignore"):  # inf − inf: still at the limit, toward
                change = gradient - self._previous
            toward = ~(change < 0.0)
        self._previous = gradient
        # On or beyond a limit (|∂H/∂θ| = ∞) the difference says nothing: a joint is held
        # (w = ∞) only while its previous velocity points further out, so it can come back.
        outward = np.sign(theta - middle) * qdot_prev > 0.0
        toward = np.where(np.isinf(gradient), outward, toward)
        return np.where(toward, 1.0 + gradient, 1.0)

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """WLN joint velocity [rad/s], shape ``(nv,)``; ``damping`` is λ."""
        weights = self.weights(state, qdot_prev)
        mu = self.damping**2
        if np.all(weights == 1.0):
            U, sigma, Vt = state.U, state.sigma, state.Vt
            scale = np.ones_like(weights)
        else:
            scale = 1.0 / np.sqrt(weights)  # W^{-1/2}; 0 for w = inf
            U, sigma, Vt = thin_svd(state.task_jacobian * scale)
        if mu > 0.0:
            gains = sigma / (sigma * sigma + mu)
        else:
            keep = sigma > rank_cutoff(sigma)
            gains = np.where(keep, 1.0 / np.where(keep, sigma, 1.0), 0.0)
        qdot = scale * (Vt.T @ (gains * (xdot @ U)))
        return self.unconstrained_output(qdot, math.sqrt(mu) if mu > 0.0 else 0.0)
