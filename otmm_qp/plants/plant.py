r"""The plant stage: what happens to a joint-velocity command between the controller and the arm.

A plant is a chain of *stages* (:class:`Plant`). Each control period ``k`` the loop does

.. math::
    \tilde q_k = m_S(\dots m_1(q_k)),\qquad
    \dot q^{a}_k = c_S(\dots c_1(\dot q^{cmd}_k)),\qquad
    (q_{k+1}, \dot q^{act}_k) = \text{body}(q_k, \dot q^{a}_k)

* ``measure`` (:math:`m_i`): what the controller sees of the true configuration ``q_k``
  (e.g. encoder noise); metrics are always computed on the true ``q_k``;
* ``command`` (:math:`c_i`): what reaches the joint servos of the command (lag, latency);
* ``advance`` (the *body*, exactly one per chain): integrates the arm over one period
  ``dt`` — the Euler integrator ``q ⊕ q̇ dt`` (:class:`~otmm_qp.plants.ideal.IdealPlant`)
  or a physics engine (:class:`~otmm_qp.plants.mujoco_plant.MujocoPlant`).

Both the command and the measurement paths run through the stages in the order they are
listed. A stage keeps its own state between periods; :meth:`Plant.reset` starts it afresh at
the start of a run.
"""

from __future__ import annotations

import abc
import math
from typing import ClassVar, NamedTuple

from otmm_qp.plants.declaration import PlantDeclaration
from otmm_qp.robots.robot import FloatArray, Robot

__all__ = ["Plant", "PlantStep"]


class PlantStep(NamedTuple):
    r"""What the body did over one control period.

    Attributes:
        q: True configuration at the end of the period, shape ``(nq,)``.
        qdot: Actual joint velocity [rad/s], shape ``(nv,)``: the velocity integrated over
            the period (Euler body) or the simulated joint velocity at its end (MuJoCo).
        torque_ratio: Largest :math:`|\tau_i|/\tau_{max,i}` over the period and the joints
            (NaN when the body has no torque model).
        saturated: Whether any joint torque was clipped at its limit during the period.
        stable: False when the body's simulation became unstable (non-finite or runaway
            state); the loop then stops and stores why.
        detail: Why the body is unstable (empty when stable).
    """

    q: FloatArray
    qdot: FloatArray
    torque_ratio: float = math.nan
    saturated: bool = False
    stable: bool = True
    detail: str = ""


class Plant(abc.ABC):
    """One stage of the plant (see the module docstring for where each hook runs).

    Subclasses implement :meth:`reset` and override the hooks they change; the defaults pass
    the command and the measurement through unchanged and have no body.
    """

    #: Registered name (set by each stage).
    name: ClassVar[str] = "plant"
    #: Whether the stage integrates the arm (implements :meth:`advance`).
    body: ClassVar[bool] = False
    #: Whether :meth:`measure` returns the true configuration unchanged.
    exact_measurement: ClassVar[bool] = True

    @abc.abstractmethod
    def reset(self, robot: Robot, q0: FloatArray, dt: float) -> None:
        """Start a run from configuration ``q0`` (nq,) with control period ``dt`` [s].

        Raises:
            ConfigError: The stage cannot run on ``robot`` (e.g. a model MuJoCo rejects);
                raised when the run is prepared, before any step.
        """

    def command(self, qdot: FloatArray) -> FloatArray:
        """The joint-velocity command (nv,) [rad/s] passed on towards the arm this period."""
        return qdot

    def measure(self, q: FloatArray) -> FloatArray:
        """What the controller sees (nq,) of the configuration ``q`` (nq,) it receives."""
        return q

    def advance(self, q: FloatArray, qdot: FloatArray) -> PlantStep:
        """Integrate the arm over one period from ``q`` (nq,) under the command ``qdot`` (nv,).

        Raises:
            NotImplementedError: The stage is not a body.
        """
        raise NotImplementedError(f"plant stage {self.name!r} does not integrate the arm")

    def declares(self, dt: float) -> PlantDeclaration:
        """What the stage declares about itself for a control period ``dt`` [s] (nothing here).

        Read by the controller's limits before a run (:mod:`otmm_qp.plants.declaration`).
        """
        return PlantDeclaration()

    def label(self) -> str:
        """Short label of the stage and its parameters, e.g. ``lag(tau=0.02)``."""
        return self.name
