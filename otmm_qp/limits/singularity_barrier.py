r"""Singularity barrier: a linearised control-barrier row on σ_min (a ``RowLimit`` of ``qp``).

With :math:`\sigma = \sigma_{min}(J_w(q))` and :math:`\nabla\sigma` its gradient
(:func:`otmm_qp.singularity.sigma_min_gradient`), the QP gets the row (discrete-time
control-barrier-function form, gain :math:`\gamma \in (0, 1]`)

.. math::
    dt\,\nabla\sigma^\top\dot q \;\ge\; -\gamma\,(\sigma - \sigma_{safe})

i.e. the first-order prediction :math:`\sigma + dt\,\nabla\sigma^\top\dot q` closes at most the
fraction γ of the distance to :math:`\sigma_{safe}` per step; γ = 1 is the plain linearised
constraint :math:`\sigma + dt\,\nabla\sigma^\top\dot q \ge \sigma_{safe}`. Below
:math:`\sigma_{safe}` the row asks σ to *grow* by γ of the deficit.

Infeasible row (relaxed with a slack). Over the box the row's largest reachable value is
:math:`r = \sum_i \max(c_i\,lb_i,\ c_i\,ub_i)`, ``c = dt∇σ``. When :math:`r` is below the
bound the row is relaxed to :math:`c^\top\dot q \ge r - 10^{-9}(1 + |r|)`: the slack
:math:`s = -\gamma(\sigma-\sigma_{safe}) - r` is the smallest that makes the QP feasible — the
limit of a slack penalised by weight :math:`\rho \to \infty`, computed in closed form instead
of with an extra variable — and the step reports status ``relaxed``. An exactly singular
start (``∇σ`` possibly zero) is therefore a normal input.

Lazy row: the QP without the row is solved first; its optimum is kept whenever it satisfies
the row (adding a constraint that the optimum satisfies leaves a convex problem's optimum
unchanged), which costs one directional derivative :math:`\dot\sigma(\dot q)`; the gradient
(``nv`` directional derivatives) and the QP with the row are computed only when it does not.
"""

from __future__ import annotations

from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.limits.limit import Box, Row, RowLimit
from otmm_qp.robots.robot import FloatArray
from otmm_qp.singularity import sigma_min_gradient, sigma_min_rate
from otmm_qp.state import KinematicState
from otmm_qp.validation import Constraints, Interval, check_params

__all__ = ["SingularityBarrier"]


class SingularityBarrier(RowLimit):
    r"""The barrier row :math:`dt\,\nabla\sigma^\top\dot q \ge -\gamma(\sigma - \sigma_{safe})`.

    See the module docstring for the row, its relaxation and why it is enforced lazily.

    Args:
        sigma_safe: :math:`\sigma_{safe} \ge 0` [task units]: the floor kept on σ_min.
        gain: :math:`\gamma \in (0, 1]` [-]: fraction of the distance to the floor that one
            step may close.

    Raises:
        ParameterError: A field that is not a number or out of range.
    """

    name: ClassVar[str] = "singularity_barrier"
    parameter_constraints: ClassVar[Constraints] = {
        "sigma_safe": Interval(Real, 0, None, closed="left"),
        "gain": Interval(Real, 0, 1, closed="right"),
    }

    def __init__(self, sigma_safe: float = 0.02, gain: float = 1.0) -> None:
        check_params(self, locals())
        self.sigma_safe = float(sigma_safe)
        self.gain = float(gain)

    def required(self, state: KinematicState) -> float:
        r""":math:`-\gamma(\sigma_{min} - \sigma_{safe})` [task units]: the row's lower bound."""
        return -self.gain * (state.sigma_min - self.sigma_safe)

    def predicted(self, state: KinematicState, qdot: FloatArray) -> float:
        r""":math:`dt\,\dot\sigma_{min}(\dot q)` [task units]: the row's value at ``qdot``."""
        return self.dt * sigma_min_rate(self.robot, state, qdot)

    def applies(self, state: KinematicState) -> bool:
        """False when ``J_w`` has fewer singular values than task rows (σ_min ≡ 0)."""
        return state.sigma.size >= state.task_dim

    def satisfied(self, state: KinematicState, qdot: FloatArray) -> bool:
        """Whether the first-order prediction at ``qdot`` meets :meth:`required`."""
        return self.predicted(state, qdot) >= self.required(state)

    def compute_row(self, state: KinematicState, box: Box) -> Row:
        """The step's row, relaxed when no ``q̇`` in ``box`` satisfies it."""
        row = self.dt * sigma_min_gradient(self.robot, state)
        required = self.required(state)
        reach = float(np.sum(np.maximum(row * box.lower, row * box.upper)))
        if reach >= required:
            return Row(row, required, 0.0)
        lower = reach - 1e-9 * (1.0 + abs(reach))
        return Row(row, lower, required - lower)
