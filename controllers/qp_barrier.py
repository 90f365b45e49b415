r"""Singularity barrier of the ``qp`` backend: a linearised control-barrier row on σ_min.

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

from collections.abc import Mapping
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from otmm_qp.exceptions import ParameterError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.singularity import sigma_min_gradient, sigma_min_rate
from otmm_qp.state import KinematicState

FIELD = "singularity_barrier"


class BarrierRow(NamedTuple):
    """The barrier row of one step: ``row·q̇ ≥ lower`` (``lower`` after relaxation).

    Attributes:
        row: ``dt·∇σ_min`` [task units·s/rad], shape ``(nv,)``.
        lower: The bound the QP enforced [task units].
        slack: ``required − lower ≥ 0`` [task units]; > 0 when the row was relaxed.
    """

    row: FloatArray
    lower: float
    slack: float


@dataclass(frozen=True)
class SingularityBarrier:
    r"""Parameters of the barrier row (see the module docstring).

    Attributes:
        sigma_safe: :math:`\sigma_{safe} \ge 0` [task units]: the floor kept on σ_min.
        gain: :math:`\gamma \in (0, 1]` [-]: fraction of the distance to the floor that one
            step may close.
    """

    sigma_safe: float = 0.02
    gain: float = 1.0

    def __post_init__(self) -> None:
        """Validate both fields."""
        for name in ("sigma_safe", "gain"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ParameterError(f"{FIELD}.{name}", f"must be a number, got {value!r}")
        if not (np.isfinite(self.sigma_safe) and self.sigma_safe >= 0.0):
            raise ParameterError(f"{FIELD}.sigma_safe", f"must be >= 0, got {self.sigma_safe}")
        if not (np.isfinite(self.gain) and 0.0 < self.gain <= 1.0):
            raise ParameterError(f"{FIELD}.gain", f"must be in (0, 1], got {self.gain}")

    @classmethod
    def from_option(
        cls, option: SingularityBarrier | Mapping[str, float] | None
    ) -> SingularityBarrier | None:
        """The barrier of a backend option: None (off), a mapping of the fields, or an instance.

        Raises:
            ParameterError: Not a mapping, an unknown key, or a field out of range.
        """
        if option is None or isinstance(option, SingularityBarrier):
            return option
        if not isinstance(option, Mapping):
            raise ParameterError(FIELD, f"must be a mapping with sigma_safe, gain; got {option!r}")
        unknown = sorted(set(option) - {"sigma_safe", "gain"})
        if unknown:
            raise ParameterError(FIELD, f"unknown key {unknown[0]!r}; allowed: sigma_safe, gain")
        return cls(**option)

    def required(self, state: KinematicState) -> float:
        r""":math:`-\gamma(\sigma_{min} - \sigma_{safe})` [task units]: the row's lower bound."""
        return -self.gain * (state.sigma_min - self.sigma_safe)

    def predicted(self, robot: Robot, state: KinematicState, qdot: FloatArray, dt: float) -> float:
        r""":math:`dt\,\dot\sigma_{min}(\dot q)` [task units]: the row's value at ``qdot``."""
        return dt * sigma_min_rate(robot, state, qdot)

    def row(self, robot: Robot, state: KinematicState, dt: float, bounds: FloatArray) -> BarrierRow:
        """The step's row, relaxed when no ``q̇`` in the box ``bounds`` (2, nv) satisfies it."""
        row = dt * sigma_min_gradient(robot, state)
        required = self.required(state)
        reach = float(np.sum(np.maximum(row * bounds[0], row * bounds[1])))
        if reach >= required:
            return BarrierRow(row, required, 0.0)
        lower = reach - 1e-9 * (1.0 + abs(reach))
        return BarrierRow(row, lower, required - lower)
