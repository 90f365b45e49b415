r"""What a control step's backend reports about its solution: one :class:`Status` per step.

The values, in the order a step is classified (the first that applies wins):

* ``nonfinite``: the backend returned NaN/inf; the controller replaced ``q̇`` by zero.
* ``infeasible``: no joint velocity satisfies the constraints and nothing was returned that
  honours them (a solver failure, or an infeasible direction-preserving step).
* ``relaxed``: the constraints were infeasible and the infeasibility policy (``hold``,
  ``dls``, or the QP's singularity-barrier slack) returned a solution of a *relaxed* problem:
  the bounds or the barrier it had to give up are honoured as closely as their priority allows.
* ``saturated``: an unconstrained backend returned a joint speed above the robot's limit,
  :math:`\exists i:\ |\dot q_i| > \dot q_{max,i}(1 + 10^{-9})` — the arm cannot execute the
  command as given (its drives would clip it). Never reported when the limits are infinite.
* ``stuck``: a direction-preserving backend realised less than its threshold fraction of the
  command.
* ``bounded``: solved with at least one joint bound active.
* ``ok``: solved with no bound active.

:class:`Status` subclasses :class:`str`, so ``status == "ok"`` and string-keyed tables keep
working.
"""

from __future__ import annotations

import enum

import numpy as np

from otmm_qp.robots.robot import FloatArray

#: Relative tolerance of :func:`exceeds_speed_limits` (absorbs the rounding of a clipped q̇).
SPEED_LIMIT_RTOL = 1e-9


class Status(str, enum.Enum):
    """Outcome of one backend solve (see the module docstring for the precise rules)."""

    OK = "ok"
    BOUNDED = "bounded"
    INFEASIBLE = "infeasible"
    RELAXED = "relaxed"
    STUCK = "stuck"
    NONFINITE = "nonfinite"
    SATURATED = "saturated"

    def __str__(self) -> str:
        """The plain value, e.g. ``ok`` (what result files and tables show)."""
        return str(self.value)


def exceeds_speed_limits(qdot: FloatArray, velocity_limits: FloatArray) -> bool:
    r"""Whether :math:`|\dot q_i| > \dot q_{max,i}(1 + 10^{-9})` for some joint ``i``.

    Args:
        qdot: Joint velocity [rad/s or m/s], shape ``(nv,)``.
        velocity_limits: ``q̇_max`` [rad/s or m/s], shape ``(nv,)``, inf where unlimited.
    """
    # One comparison and the array method (no np.max wrapper): this runs on every step.
    # inf limits never compare smaller; a NaN speed compares False (the nonfinite guard reports it).
    return bool((np.abs(qdot) > velocity_limits * (1.0 + SPEED_LIMIT_RTOL)).any())
