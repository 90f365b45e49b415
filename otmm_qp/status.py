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

:func:`classify` applies these rules, once per step, in
:meth:`otmm_qp.controller.Controller.step`; a backend reports only what its solve knows
(``ok``, ``bounded``, ``stuck``, ``relaxed``, ``infeasible``). :class:`Status` members carry
their attributes (``claims_solution``, ``relaxes_bound``, ``marker``), which reports and figures
read instead of listing names. :class:`Status` subclasses :class:`str`, so ``status == "ok"``
and string-keyed tables keep working.
"""

from __future__ import annotations

import enum
import math

import numpy as np
import numpy.typing as npt

from otmm_qp.robots.robot import FloatArray

#: Joint speed [rad/s] above which a step is ``diverging`` (and a run ``blow_up``): no arm's
#: drive reaches it (industrial joints top out near 10 rad/s), so beyond it the controller,
#: not the arm, sets the speed.
DIVERGENCE_SPEED = 100.0

#: Relative tolerance of :func:`exceeds_speed_limits` (absorbs the rounding of a clipped q̇).
SPEED_LIMIT_RTOL = 1e-9


class Status(str, enum.Enum):
    """Outcome of one control step (see the module docstring for the precise rules).

    Each member carries what reports, figures and the classification read:

    Attributes:
        claims_solution: The step returned a usable solution of the problem as posed (``ok``,
            ``bounded``, ``saturated``, ``stuck``); ``diverging`` overrides only these.
        relaxes_bound: A bound (or the barrier) was given up or could not be met on the step
            (``relaxed``, ``infeasible``): the report counts these per run.
        marker: Figure marker style ``(marker, colour)`` of matplotlib, or None (not marked).
    """

    OK = ("ok", True, False, None)
    BOUNDED = ("bounded", True, False, ("v", "tab:orange"))
    INFEASIBLE = ("infeasible", False, True, ("X", "tab:red"))
    RELAXED = ("relaxed", False, True, ("P", "tab:pink"))
    STUCK = ("stuck", True, False, ("s", "tab:purple"))
    NONFINITE = ("nonfinite", False, False, ("D", "black"))
    SATURATED = ("saturated", True, False, ("^", "tab:olive"))
    DIVERGING = ("diverging", False, False, ("*", "tab:brown"))

    claims_solution: bool
    relaxes_bound: bool
    marker: tuple[str, str] | None

    def __new__(
        cls,
        value: str,
        claims_solution: bool,
        relaxes_bound: bool,
        marker: tuple[str, str] | None,
    ) -> Status:
        """A member whose value is the plain name and whose attributes are the rest."""
        member = str.__new__(cls, value)
        member._value_ = value
        member.claims_solution = claims_solution
        member.relaxes_bound = relaxes_bound
        member.marker = marker
        return member

    def __str__(self) -> str:
        """The plain value, e.g. ``ok`` (what result files and tables show)."""
        return str(self.value)


def speed_limit_thresholds(velocity_limits: FloatArray) -> FloatArray:
    r"""The thresholds :math:`\dot q_{max,i}(1 + 10^{-9})` [rad/s or m/s], shape ``(nv,)``.

    Computed once per run (a backend's ``bind``), so the per-step test is one comparison.
    """
    return np.asarray(velocity_limits, dtype=float) * (1.0 + SPEED_LIMIT_RTOL)


def exceeds_speed_limits(
    qdot: FloatArray, thresholds: FloatArray, work: SpeedWork | None = None
) -> bool:
    r"""Whether :math:`|\dot q_i| > \dot q_{max,i}(1 + 10^{-9})` for some joint ``i``.

    Args:
        qdot: Joint velocity [rad/s or m/s], shape ``(nv,)``.
        thresholds: :func:`speed_limit_thresholds` of the limits, shape ``(nv,)``, inf where
            unlimited.
        work: Preallocated buffers (:class:`SpeedWork`) so the test allocates nothing; None:
            temporaries.
    """
    # inf thresholds never compare smaller; a NaN speed compares False (the nonfinite guard
    # reports it).
    if work is None:
        return bool((np.abs(qdot) > thresholds).any())
    np.abs(qdot, work.magnitude)
    np.greater(work.magnitude, thresholds, work.exceeds)
    return True in work.exceeds.tolist()  # a third of ndarray.any's cost on nv joints


class SpeedWork:
    """Preallocated buffers of the per-step speed tests (allocated once per run).

    Attributes:
        magnitude: ``|q̇|`` [rad/s], shape ``(nv,)``.
        exceeds: ``|q̇_i| >`` threshold, shape ``(nv,)``, bool.
    """

    __slots__ = ("exceeds", "magnitude")

    def __init__(self, nv: int) -> None:
        self.magnitude: FloatArray = np.empty(nv)
        self.exceeds: npt.NDArray[np.bool_] = np.empty(nv, dtype=bool)


def quiet_speed_squared(thresholds: FloatArray | None, divergence_speed: float) -> float:
    r"""A bound :math:`s` such that :math:`\|\dot q\|_2^2 < s` rules out every speed rule.

    .. math:: s = \min\big(\dot q_{div}^2,\ (\min_i t_i\,(1 - 10^{-6}))^2\big)

    (``t`` the :func:`speed_limit_thresholds`; no ``t`` term when ``thresholds`` is None).
    Below it :math:`|\dot q_i| \le \|\dot q\|_2 < \min_i t_i \le t_i` for every joint (the
    margin covers the rounding of the dot product), so neither ``saturated`` nor ``diverging``
    can apply and :func:`classify` would return the backend's status: the controller skips it.
    NaN and inf fail the ``<`` test.
    """
    quiet = divergence_speed * divergence_speed
    if thresholds is not None and thresholds.size:
        floor = float(np.min(thresholds)) * (1.0 - 1e-6)
        quiet = min(quiet, floor * floor)
    return quiet


#: Statuses a ``diverging`` step overrides (plain strings of plugins hash alike).
_SOLVED = frozenset(status for status in Status if status.claims_solution)


def classify(
    status: str,
    qdot: FloatArray,
    speed_squared: float,
    speed_thresholds: FloatArray | None,
    divergence_speed: float,
    work: SpeedWork | None = None,
) -> str:
    r"""The step's status, from the backend's and its ``q̇``: the one classification.

    In order (the first that applies wins):

    1. ``nonfinite`` when :math:`\|\dot q\|_2^2` is not finite (the caller then zeroes q̇);
    2. ``saturated`` when the backend said ``ok``, does not enforce limits
       (``speed_thresholds`` given) and :func:`exceeds_speed_limits`;
    3. ``diverging`` when the status claims a solution and :math:`\|\dot q\|_\infty > \dot q_{div}`;
    4. the backend's status.

    Args:
        status: The backend's status of the step.
        qdot: Joint velocity [rad/s], shape ``(nv,)``.
        speed_squared: :math:`\|\dot q\|_2^2` [rad²/s²] (the caller has it).
        speed_thresholds: :func:`speed_limit_thresholds` of the robot for a backend that does
            not enforce limits; None for one that does (or a robot with no finite limit).
        divergence_speed: :math:`\dot q_{div}` [rad/s], > 0 (inf: never diverging).
        work: Preallocated buffers (:class:`SpeedWork`, shape ``(nv,)``); None: temporaries.
    """
    if not math.isfinite(speed_squared):
        return Status.NONFINITE
    if (
        speed_thresholds is not None
        and status == Status.OK
        and exceeds_speed_limits(qdot, speed_thresholds, work)
    ):
        status = Status.SATURATED
    # ‖q̇‖∞ ≤ ‖q̇‖₂: the cheap 2-norm test rules out almost every step before the exact one.
    if speed_squared <= divergence_speed * divergence_speed:
        return status
    if status in _SOLVED:
        magnitude = np.abs(qdot) if work is None else np.abs(qdot, work.magnitude)
        if float(magnitude.max()) > divergence_speed:
            return Status.DIVERGING
    return status
