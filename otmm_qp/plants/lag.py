r"""First-order joint servo lag: the actual joint velocity follows the command with time constant τ.

Two discretisations, named (the issue gives the first; both are the same to first order in
dt/τ):

* ``update: exact`` (default, zero-order hold):
  :math:`\dot q^{a}_k = \dot q^{a}_{k-1} + \alpha(\dot q^{cmd}_k - \dot q^{a}_{k-1}),\
  \alpha = 1 - e^{-dt/\tau}` — the exact sampled response of
  :math:`\tau\,\ddot q^{a} + \dot q^{a} = \dot q^{cmd}`; stable for every τ > 0 and
  :math:`\alpha \to 1` (the ideal plant) as τ → 0;
* ``update: euler``: :math:`\alpha = dt/\tau`, the issue's formula; τ < dt would overshoot
  (α > 1) and is refused; τ = dt gives α = 1, the ideal plant exactly.

The servo starts at rest (:math:`\dot q^{a}_{-1} = 0`).
"""

from __future__ import annotations

import math
from numbers import Real
from typing import ClassVar, Literal

import numpy as np

from otmm_qp.exceptions import ParameterError
from otmm_qp.plants.declaration import PlantDeclaration
from otmm_qp.plants.plant import Plant
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.validation import Constraints, Interval, OneOf, check_params

__all__ = ["LagPlant"]


class LagPlant(Plant):
    """First-order lag of the velocity command.

    Args:
        tau: Servo time constant τ [s], finite and > 0.
        update: ``exact`` (α = 1 − e^{−dt/τ}) or ``euler`` (α = dt/τ, needs τ ≥ dt).
    """

    name: ClassVar[str] = "lag"
    parameter_constraints: ClassVar[Constraints] = {
        "tau": Interval(Real, 0, None, closed="neither", unit="s"),
        "update": OneOf("exact", "euler"),
    }

    def __init__(self, tau: float, update: Literal["exact", "euler"] = "exact") -> None:
        check_params(self, locals())
        self.tau = float(tau)
        self.update = update
        self.alpha = 1.0
        self._actual = np.zeros(0)

    def reset(self, robot: Robot, q0: FloatArray, dt: float) -> None:
        """Servo at rest; α from ``dt`` [s].

        Raises:
            ParameterError: ``update: euler`` with τ < dt (α > 1 would overshoot).
        """
        if self.update == "euler":
            if self.tau < dt:
                raise ParameterError(
                    "tau",
                    f"with update: euler tau must be >= dt = {dt:g} s (alpha = dt/tau <= 1), "
                    f"got {self.tau:g}; use update: exact for smaller tau",
                )
            self.alpha = dt / self.tau
        else:
            self.alpha = -math.expm1(-dt / self.tau)
        self._actual = np.zeros(robot.nv)

    def command(self, qdot: FloatArray) -> FloatArray:
        r""":math:`\dot q^{a} \leftarrow \dot q^{a} + \alpha(\dot q^{cmd} - \dot q^{a})` [rad/s]."""
        self._actual = self._actual + self.alpha * (qdot - self._actual)
        return self._actual

    def declares(self, dt: float) -> PlantDeclaration:
        r"""The lag as a zero-order-hold-exact τ [s].

        τ itself, or for ``update: euler`` (α = dt/τ) the τ' with the same α,
        :math:`\tau' = -dt/\ln(1 - dt/\tau)` (0 at α = 1).
        """
        if self.update == "exact":
            return PlantDeclaration(lags=(self.tau,))
        alpha = min(1.0, dt / self.tau)
        return PlantDeclaration(lags=(0.0 if alpha >= 1.0 else -dt / math.log1p(-alpha),))

    def label(self) -> str:
        """``lag(tau=…)`` (with ``,euler`` for that update)."""
        suffix = ",euler" if self.update == "euler" else ""
        return f"lag(tau={self.tau:g}{suffix})"
