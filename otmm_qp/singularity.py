r"""Derivatives of the smallest singular value σ_min of the (weighted) task Jacobian.

For a simple σ_min of :math:`J_w = W J` with singular vectors :math:`u_s, v_s`,

.. math::
    \frac{\partial \sigma_{min}}{\partial q_k} = u_s^\top W \frac{\partial J}{\partial q_k} v_s,
    \qquad
    \dot\sigma_{min} = u_s^\top W \dot J(q, \dot q)\, v_s

(first-order perturbation of a simple singular value). Both use the robot's
:meth:`~otmm_qp.robots.Robot.jacobian_derivative` (analytic for planar and Pinocchio arms,
central differences otherwise) and the step's shared SVD. Where σ_min is repeated the SVD's
choice of :math:`u_s, v_s` gives one element of the (generalised) gradient. When the arm
has fewer joints than task rows, σ_min ≡ 0 and both derivatives are zero.
"""

from __future__ import annotations

import numpy as np

from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState


def _structurally_singular(state: KinematicState) -> bool:
    return state.sigma.size < state.task_dim


def sigma_min_rate(robot: Robot, state: KinematicState, qdot: FloatArray) -> float:
    r"""Rate :math:`\dot\sigma_{min} = u_s^\top W \dot J(q, \dot q) v_s` [task units/s].

    Args:
        robot: The arm of ``state``.
        state: Kinematic state (its SVD is used, not recomputed).
        qdot: Joint velocity [rad/s], shape ``(nv,)``.
    """
    if _structurally_singular(state):
        return 0.0
    u_s = state.U[:, -1] * state.weight
    rate = robot.jacobian_derivative(state.q, qdot)
    return float(u_s @ rate @ state.Vt[-1])


def sigma_min_gradient(robot: Robot, state: KinematicState) -> FloatArray:
    r"""Gradient :math:`\nabla_q \sigma_{min}`, shape ``(nv,)`` [task units/rad].

    One directional derivative of ``J`` per joint: ``g_k = u_sᵀ W (∂J/∂q_k) v_s``.
    """
    nv = state.Vt.shape[1]
    gradient = np.zeros(nv)
    if _structurally_singular(state):
        return gradient
    u_s = state.U[:, -1] * state.weight
    v_s = state.Vt[-1]
    basis = np.eye(nv)
    for k in range(nv):
        gradient[k] = u_s @ robot.jacobian_derivative(state.q, basis[k]) @ v_s
    return gradient
