r"""Damped least squares from the shared SVD, for any damping value.

.. math::
    \dot q = J^\top (JJ^\top + \mu I)^{-1}\dot x
           = \sum_i \frac{\sigma_i}{\sigma_i^2 + \mu}\,(u_i^\top \dot x)\, v_i

``μ ≥ 0`` is the term added to :math:`JJ^\top` (``μ = λ²`` for a damping factor λ).
"""

from __future__ import annotations

import numpy as np

from otmm_qp.backends.backend import RCOND, truncated_pseudoinverse_apply
from otmm_qp.robots.robot import FloatArray
from otmm_qp.state import KinematicState


def damped_least_squares(
    state: KinematicState, xdot: FloatArray, mu: float, work: FloatArray | None = None
) -> FloatArray:
    r"""``Jᵀ(JJᵀ + μI)⁻¹ẋ`` [rad/s], shape ``(nv,)``; the truncated pseudoinverse when μ ≤ 0.

    .. math::
        \dot q = J^\top (JJ^\top + \mu I)^{-1}\dot x
               = \sum_i \frac{\sigma_i}{\sigma_i^2 + \mu}\,(u_i^\top \dot x)\, v_i

    from the shared SVD (``μ = λ²`` for a damping factor λ [task units]).

    Args:
        state: The step's kinematic state.
        xdot: ``ẋ_w``, shape ``(n,)``.
        mu: ``μ ≥ 0`` [task units²].
        work: :func:`svd_work` buffers, shape ``(2, k)``; None: temporaries.

    Returns:
        ``q̇`` [rad/s], shape ``(nv,)``, a new array.
    """
    if mu <= 0.0:
        return truncated_pseudoinverse_apply(state, xdot, RCOND, work)
    sigma = state.sigma
    xdot = np.asarray(xdot, dtype=float)
    if work is not None and work.shape[1] == sigma.size:
        gains, coefficients = work[0], xdot.dot(state.U, work[1])
        np.multiply(sigma, sigma, gains)
    else:
        gains, coefficients = sigma * sigma, xdot.dot(state.U)
    np.add(gains, mu, gains)
    np.divide(sigma, gains, gains)  # σᵢ/(σᵢ² + μ)
    np.multiply(coefficients, gains, coefficients)  # (uᵢᵀẋ) σᵢ/(σᵢ² + μ)
    result: FloatArray = coefficients.dot(state.Vt)
    return result
