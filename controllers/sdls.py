"""Selective damped least squares (Buss & Kim 2005)."""

from __future__ import annotations

from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.backends.backend import RCOND, Backend, BackendOutput, rank_cutoff
from otmm_qp.robots.robot import FloatArray
from otmm_qp.state import KinematicState
from otmm_qp.validation import Constraints, Interval, check_params


def clamp_max_abs(w: FloatArray, d: float) -> FloatArray:
    """Scale ``w`` so that ``max|w_i| ≤ d`` (Buss & Kim's ClampMaxAbs)."""
    largest = float(np.max(np.abs(w))) if w.size else 0.0
    return w if largest <= d else w * (d / largest)


class SelectiveDampedLeastSquaresBackend(Backend):
    r"""SDLS: each singular component gets its own joint-angle clamp.

    Per step, with ``e = ẋ·dt`` the task displacement and ``ρ_j = ‖J_{:,j}‖``:

    .. math::
        \alpha_i = u_i^\top e,\quad N_i = \|u_i\| = 1,\quad
        M_i = \sigma_i^{-1}\sum_j |v_{ji}|\,\rho_j,\quad
        \gamma_i = \min(1, N_i/M_i)\,\gamma_{max}

        \Delta q = \mathrm{Clamp}\Big(\sum_i \mathrm{Clamp}(\sigma_i^{-1}\alpha_i v_i,\ \gamma_i),\
        \gamma_{max}\Big),\qquad \dot q = \Delta q/dt

    (single end-effector form; singular values below ``rcond·σ_max`` are skipped). Status
    ``saturated`` when ``q̇`` exceeds the robot's joint speed limits.

    Args:
        gamma_max: Largest joint change per step γ_max > 0 [rad] (Buss & Kim: π/4).
        rcond: Relative threshold below which a singular value is ignored.
    """

    name = "sdls"
    parameter_constraints: ClassVar[Constraints] = {
        "gamma_max": Interval(Real, 0, None, closed="neither", unit="rad"),
        "rcond": Interval(Real, 0, 1, closed="left"),
    }

    def __init__(self, gamma_max: float = float(np.pi / 4), rcond: float = RCOND) -> None:
        check_params(self, locals())
        self.gamma_max = float(gamma_max)
        self.rcond = float(rcond)

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """SDLS joint velocity [rad/s], shape ``(nv,)``."""
        sigma, U, Vt = state.sigma, state.U, state.Vt
        column_norms = np.linalg.norm(state.task_jacobian, axis=0)  # ρ_j, (nv,)
        displacement = xdot * self.dt  # e, (n,)
        delta = np.zeros(Vt.shape[1])
        cutoff = rank_cutoff(sigma, self.rcond)
        for i in range(sigma.size):
            if sigma[i] <= cutoff:
                continue
            v_i = Vt[i]
            alpha_i = float(U[:, i] @ displacement)
            m_i = float(np.abs(v_i) @ column_norms) / sigma[i]
            gamma_i = min(1.0, 1.0 / m_i) * self.gamma_max if m_i > 0 else self.gamma_max
            delta += clamp_max_abs((alpha_i / sigma[i]) * v_i, gamma_i)
        return self.unconstrained_output(clamp_max_abs(delta, self.gamma_max) / self.dt)
