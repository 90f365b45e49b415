r"""Damped least squares from the shared SVD, for any damping value.

.. math::
    \dot q = J^\top (JJ^\top + \mu I)^{-1}\dot x
           = \sum_i \frac{\sigma_i}{\sigma_i^2 + \mu}\,(u_i^\top \dot x)\, v_i

``μ ≥ 0`` is the term added to :math:`JJ^\top` (``μ = λ²`` for a damping factor λ).
"""

from __future__ import annotations

from otmm_qp.backends.backend import truncated_pseudoinverse_apply
from otmm_qp.robots.robot import FloatArray
from otmm_qp.state import KinematicState


def damped_least_squares(state: KinematicState, xdot: FloatArray, mu: float) -> FloatArray:
    """``Jᵀ(JJᵀ + μI)⁻¹ẋ`` [rad/s], shape ``(nv,)``; the truncated pseudoinverse when μ = 0."""
    if mu <= 0.0:
        return truncated_pseudoinverse_apply(state, xdot)
    sigma = state.sigma
    gains = sigma / (sigma * sigma + mu)  # (k,)
    return state.Vt.T @ (gains * (state.U.T @ xdot))
