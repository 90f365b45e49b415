r"""Null-space ascent of Yoshikawa's manipulability for redundant arms."""

from __future__ import annotations

from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.backends.backend import Backend, BackendOutput
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.validation import Constraints, Interval, check_params

from .damping import damped_least_squares


def manipulability(state: KinematicState) -> float:
    r"""Yoshikawa's measure :math:`w = \sqrt{\det(J_w J_w^\top)} = \prod_i \sigma_i` [-].

    Zero when the arm has fewer joints than task rows.
    """
    if state.sigma.size < state.task_dim:
        return 0.0
    return float(np.prod(state.sigma))


def manipulability_gradient(robot: Robot, state: KinematicState) -> FloatArray:
    r"""Gradient :math:`\nabla_q w`, shape ``(nv,)`` [1/rad].

    .. math::
        \frac{\partial w}{\partial q_k} = w\,\mathrm{tr}\big((JJ^\top)^{-1}
        \tfrac{\partial J}{\partial q_k}J^\top\big)
        = \sum_i \Big(\prod_{j \ne i}\sigma_j\Big)\,u_i^\top \frac{\partial J}{\partial q_k} v_i

    (the SVD form, equal to the trace form wherever :math:`JJ^\top` is invertible, and
    still defined at a singularity). ``J`` is the weighted task Jacobian :math:`W J`;
    :math:`\partial J/\partial q_k` comes from :meth:`Robot.jacobian_derivative`.
    """
    nv = state.Vt.shape[1]
    gradient = np.zeros(nv)
    sigma = state.sigma
    if sigma.size < state.task_dim:
        return gradient
    k = sigma.size
    # Π_{j≠i} σ_j without dividing by a σ that may be zero.
    others = np.array([np.prod(np.delete(sigma, i)) for i in range(k)])  # (k,)
    weighted_U = state.U * state.weight[:, None]  # (n, k): Wᵀu_i
    basis = np.eye(nv)
    for joint in range(nv):
        derivative = robot.jacobian_derivative(state.q, basis[joint])  # ∂J/∂q_k, (n, nv)
        projected = weighted_U.T @ derivative @ state.Vt.T  # (k, k): u_iᵀ W ∂J v_j
        gradient[joint] = float(others @ np.diag(projected))
    return gradient


class ManipulabilityBackend(Backend):
    r"""Pseudoinverse (or DLS) plus a null-space step up the manipulability gradient.

    .. math::
        \dot q = J_w^{\#}\dot x + k\,(I - J_w^{+}J_w)\,\nabla_q w

    with :math:`J_w^{\#}` the truncated pseudoinverse (``damping = 0``) or DLS
    :math:`J^\top(JJ^\top+\lambda^2 I)^{-1}`, and the null-space projector built from the
    shared SVD, :math:`I - V_r V_r^\top` over the ``r`` singular values above
    ``1e-10·σ_max`` (Yoshikawa 1985; the gradient-projection method of Liégeois 1977).
    The secondary motion never changes the task velocity
    (:math:`J_w (I - J_w^+J_w) = 0`), so on non-redundant arms it vanishes and the backend
    is its primary inverse. :func:`manipulability_gradient` gives :math:`\nabla_q w`.

    Args:
        gain: Null-space gain ``k ≥ 0`` [rad²/s] (rad/s per unit of ∂w/∂q).
        damping: DLS damping λ ≥ 0 [task units] of the primary inverse.
    """

    name = "manipulability"
    parameter_constraints: ClassVar[Constraints] = {
        "gain": Interval(Real, 0, None, closed="left"),
        "damping": Interval(Real, 0, None, closed="left"),
    }

    def __init__(self, gain: float = 1.0, damping: float = 0.0) -> None:
        check_params(self, locals())
        self.gain = float(gain)
        self.damping = float(damping)

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Primary inverse plus the projected gradient step [rad/s], shape ``(nv,)``."""
        qdot = damped_least_squares(state, xdot, self.damping**2)
        nv = state.Vt.shape[1]
        if self.gain == 0.0 or state.sigma.size < state.task_dim or nv <= state.task_dim:
            return BackendOutput(qdot, damping=self.damping)
        gradient = manipulability_gradient(self.robot, state)
        cutoff = max(1e-10 * float(state.sigma[0]), np.finfo(float).tiny)
        rows = state.Vt[state.sigma > cutoff]  # (r, nv)
        null_step = gradient - rows.T @ (rows @ gradient)
        return BackendOutput(qdot + self.gain * null_step, damping=self.damping)
