r"""J-PARSE (Guptasarma et al., 2025): safety Jacobian, projection and singular feedback."""

from __future__ import annotations

import math

import numpy as np

from otmm_qp.backends.backend import Backend, BackendOutput
from otmm_qp.exceptions import ParameterError
from otmm_qp.robots.robot import FloatArray
from otmm_qp.state import KinematicState


class JParseBackend(Backend):
    r"""J-PARSE inverse from the shared SVD :math:`J_w = \sum_i \sigma_i u_i v_i^\top`.

    Guptasarma, Kennedy, Srinivasan, Schwager, "J-PARSE: Jacobian-based Projection
    Algorithm for Resolving Singularities Effectively in Inverse Kinematic Control of
    Serial Manipulators" (2025); reference code armlabstanford/jparse ``jparse/jparse.py``
    (read, not copied). With the threshold :math:`\sigma_\gamma = \gamma\,\sigma_{max}`:

    * safety Jacobian: :math:`J_s = \sum_i \max(\sigma_i, \sigma_\gamma)\, u_i v_i^\top`;
    * projection onto the non-singular directions:
      :math:`P = J_p J_p^+ = \sum_{\sigma_i > \sigma_\gamma} u_i u_i^\top`;
    * singular feedback: :math:`\Phi = \sum_{\sigma_i \le \sigma_\gamma}
      \frac{\sigma_i}{\sigma_\gamma} u_i u_i^\top`, scaled by the gain :math:`K`;

    .. math::
        \dot q = J_s^+\,(P + K\,\Phi)\,\dot x
        = \sum_{\sigma_i > \sigma_\gamma} \frac{u_i^\top\dot x}{\sigma_i}\,v_i
        + K\sum_{\sigma_i \le \sigma_\gamma} \frac{\sigma_i}{\sigma_\gamma^2}
          \,(u_i^\top\dot x)\,v_i .

    The gain along a singular direction, :math:`K\sigma_i/\sigma_\gamma^2`, is bounded by
    :math:`K/\sigma_\gamma` and vanishes at σ_i = 0, so the joint speed is bounded and
    continuous through a singularity. As in the reference code, Φ acts on the whole command
    (feed-forward plus the CLIK feedback of the loop mode). Task rows the arm cannot move
    at all (``nv < n``) have σ = 0 and get nothing.

    Args:
        gamma: Threshold γ ∈ (0, 1) relative to σ_max (reference default 0.1).
        singular_gain: Gain K ≥ 0 of the feedback along singular directions (default 1).
    """

    name = "jparse"

    def __init__(self, gamma: float = 0.1, singular_gain: float = 1.0) -> None:
        if not (isinstance(gamma, int | float) and math.isfinite(gamma) and 0.0 < gamma < 1.0):
            raise ParameterError("gamma", f"must be in (0, 1), got {gamma!r}")
        if not (
            isinstance(singular_gain, int | float)
            and math.isfinite(singular_gain)
            and singular_gain >= 0.0
        ):
            raise ParameterError(
                "singular_gain", f"must be a finite number >= 0, got {singular_gain!r}"
            )
        self.gamma = float(gamma)
        self.singular_gain = float(singular_gain)

    def gains(self, sigma: FloatArray) -> FloatArray:
        r"""Per-direction gains :math:`1/\sigma_i` or :math:`K\sigma_i/\sigma_\gamma^2`, ``(k,)``.

        Units [rad/(task unit)]; all zero when σ_max = 0.
        """
        if not sigma.size or not sigma[0] > 0.0:
            return np.zeros_like(sigma)
        threshold = self.gamma * float(sigma[0])
        singular = sigma <= threshold
        safe = np.where(singular, 1.0, sigma)  # no division by a (near) zero σ
        return np.where(singular, self.singular_gain * sigma / threshold**2, 1.0 / safe)

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """``q̇ = J_s⁺ (P + KΦ) ẋ_w`` [rad/s], shape ``(nv,)``."""
        qdot: FloatArray = state.Vt.T @ (self.gains(state.sigma) * (xdot @ state.U))
        return BackendOutput(qdot)
