r"""What a control step's backend reports about its solution: one :class:`Status` per step.

The values, in the order a step is classified (the first that applies wins):

* ``nonfinite``: the backend returned NaN/inf; the controller replaced ``q̇`` by zero.
* ``infeasible``: no joint velocity satisfies the constraints and nothing was returned that
  honours them (a solver failure, or an infeasible direction-preserving step).
* ``relaxed``: the constraints were infeasible and the infeasibility policy (``hold``,
  ``dls``, or the QP's singularity-barrier slack) returned a solution of a *relaxed* problem:
  the bounds or the barrier it had to give up are honoured as closely as their priority allows.
* ``diverging``: the joint speed is beyond any arm's reach,
  :math:`\|\dot q\|_\infty > \dot q_{div}` — reported for every backend, with or without
  speed limits (a pseudoinverse spinning at 10³ rad/s on a limitless arm is not ``ok``).
  ``q̇_div`` is the experiment's (or study's) ``metrics.blow_up_speed``, so the status and the
  ``blow_up`` metric agree; :data:`DIVERGENCE_SPEED` (100 rad/s, the metric's default) for a
  :class:`~otmm_qp.controller.Controller` built without a config.
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

#: Joint speed [rad/s] above which a step is ``diverging`` (and a run ``blow_up``): no arm's
#: drive reaches it (industrial joints top out near 10 rad/s), so beyond it the controller,
#: not the arm, sets the speed.
DIVERGENCE_SPEED = 100.0

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
    DIVERGING = "diverging"

    def __str__(self) -> str:
        """The plain value, e.g. ``ok`` (what result files and tables show)."""
        return str(self.value)


def speed_limit_thresholds(velocity_limits: FloatArray) -> FloatArray:
    r"""The thresholds :math:`\dot q_{max,i}(1 + 10^{-9})` [rad/s or m/s], shape ``(nv,)``.

    Computed once per run (a backend's ``bind``), so the per-step test is one comparison.
    """
    return np.asarray(velocity_limits, dtype=float) * (1.0 + SPEED_LIMIT_RTOL)


def exceeds_speed_limits(qdot: FloatArray, thresholds: FloatArray) -> bool:
    r"""Whether :math:`|\dot q_i| > \dot q_{max,i}(1 + 10^{-9})` for some joint ``i``.

    Args:
        qdot: Joint velocity [rad/s or m/s], shape ``(nv,)``.
        thresholds: :func:`speed_limit_thresholds` of the limits, shape ``(nv,)``, inf where
            unlimited.
    """
    # inf thresholds never compare smaller; a NaN speed compares False (the nonfinite guard
    # reports it).
    return bool((np.abs(qdot) > thresholds).any())


#: Statuses a ``diverging`` step overrides: the ones that claim a usable solution.
_SOLVED = frozenset({Status.OK, Status.BOUNDED, Status.SATURATED, Status.STUCK})


def classify_divergence(
    status: str, speed_squared: float, qdot: FloatArray, divergence_speed: float
) -> str:
    r"""``diverging`` if a solved step has :math:`\|\dot q\|_\infty > \dot q_{div}`, else as is.

    Args:
        status: The backend's status of the step.
        speed_squared: :math:`\|\dot q\|_2^2` [rad²/s²] (the caller's finiteness check has it).
        qdot: Joint velocity [rad/s], shape ``(nv,)``, finite.
        divergence_speed: :math:`\dot q_{div}` [rad/s], > 0.
    """
    # ‖q̇‖∞ ≤ ‖q̇‖₂: the cheap 2-norm test rules out almost every step before the exact one.
    if speed_squared <= divergence_speed * divergence_speed or status not in _SOLVED:
        return status
    return Status.DIVERGING if float(np.abs(qdot).max()) > divergence_speed else status
