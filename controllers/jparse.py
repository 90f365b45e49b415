r"""J-PARSE (Guptasarma et al., 2025): safety Jacobian, projection and singular feedback."""

from __future__ import annotations

from collections.abc import Mapping
from numbers import Real
from typing import Any, ClassVar

import numpy as np

from otmm_qp.backends.backend import Backend, BackendOutput
from otmm_qp.exceptions import ParameterError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.validation import Constraints, InstanceOf, Interval, check_params

from .secondary_tasks import SecondaryTask, secondary_task_from

#: ``secondary:`` of the backends that take a joint-space secondary task.
SECONDARY = InstanceOf((Mapping, SecondaryTask), "a mapping {type: posture | joint_limits, ...}")


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

    **As its authors run it** (``manipulator_control/scripts/xarm_vel_main_experiment.py``
    and ``jparse_cls.py`` of the reference code, read): the command is the pose error times
    *separate* gains for the position and orientation rows, and a secondary joint motion is
    added through the safety Jacobian's null space:

    .. math::
        \dot q = J_s^+(P + K\Phi)\,G\,\dot x + (I - J_s^+J_s)\,\dot q_2,\qquad
        G = \mathrm{diag}(k_p I_3,\ k_o I_3)

    with :math:`I - J_s^+J_s = I - V V^\top` (``J_s`` has full row rank whenever σ_max > 0)
    and :math:`\dot q_2` a ``secondary`` task — the authors use a posture pull
    :math:`\mathrm{clip}(-k(q - q_{home}), \pm 0.6)` rad/s (``posture`` with ``gain``,
    ``q_nominal``, ``max_speed: 0.6``). Their loop has no feed-forward, so
    :math:`G\dot x_c = G\,K_{clik}\,e` is exactly their :math:`K_p e` for a held target in
    the ``clik`` loop mode with ``clik_gain: 1``; on a moving target :math:`G` also scales the
    feed-forward (a reading the authors' code does not meet). Their per-row *singular*
    gains are commented out in that code; one ``singular_gain`` (their ``ks``) is used.
    Their error clipping (0.1 m on the real arm) is not part of the backend.

    Args:
        gamma: Threshold γ ∈ (0, 1) relative to σ_max (reference default 0.1).
        singular_gain: Gain K ≥ 0 of the feedback along singular directions (default 1).
        position_gain: :math:`k_p` ≥ 0 on the position rows (the first 3 of a pose task,
            all rows of a position task) (default 1).
        orientation_gain: :math:`k_o` ≥ 0 on the orientation rows of a pose task (default 1;
            must stay 1 on position tasks).
        secondary: ``{type: posture | joint_limits, ...}`` for the null-space term; ``None``
            (default): none.
    """

    name = "jparse"
    parameter_constraints: ClassVar[Constraints] = {
        "gamma": Interval(Real, 0, 1, closed="neither"),
        "singular_gain": Interval(Real, 0, None, closed="left"),
        "position_gain": Interval(Real, 0, None, closed="left"),
        "orientation_gain": Interval(Real, 0, None, closed="left"),
        "secondary": [SECONDARY, None],
    }

    def __init__(
        self,
        gamma: float = 0.1,
        singular_gain: float = 1.0,
        position_gain: float = 1.0,
        orientation_gain: float = 1.0,
        secondary: SecondaryTask | Mapping[str, Any] | None = None,
    ) -> None:
        check_params(self, locals())
        self.gamma = float(gamma)
        self.singular_gain = float(singular_gain)
        self.position_gain = float(position_gain)
        self.orientation_gain = float(orientation_gain)
        self.secondary = secondary_task_from(secondary)
        self._row_gains: FloatArray | None = None

    def bind(self, robot: Robot, dt: float) -> None:
        """Build the row gains for the robot's task and bind the secondary task."""
        n = robot.task_dim
        if robot.task_kind == "pose" and n == 6:
            gains = np.array([self.position_gain] * 3 + [self.orientation_gain] * 3)
        else:
            if self.orientation_gain != 1.0:
                raise ParameterError(
                    "orientation_gain",
                    f"applies to pose tasks only; this task has {n} position rows",
                )
            gains = np.full(n, self.position_gain)
        self._row_gains = None if np.all(gains == 1.0) else gains
        if self.secondary is not None:
            self.secondary.bind(robot)
        super().bind(robot, dt)

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
        """``q̇ = J_s⁺ (P + KΦ) G ẋ_w + (I − J_s⁺J_s) q̇_2`` [rad/s], shape ``(nv,)``."""
        if self._row_gains is not None:
            xdot = self._row_gains * xdot
        qdot: FloatArray = state.Vt.T @ (self.gains(state.sigma) * (xdot @ state.U))
        if self.secondary is not None:
            q2 = self.secondary.joint_velocity(self.robot, state)
            if state.sigma.size and state.sigma[0] > 0.0:
                q2 = q2 - state.Vt.T @ (state.Vt @ q2)  # (I − J_s⁺J_s) q̇_2
            qdot = qdot + q2
        return BackendOutput(qdot)
