r"""The one trust-region loop of the offline reference: ratio, radius, acceptance, stop tests.

A subproblem (:class:`Subproblem`) knows its merit function ``φ`` and, at an iterate ``Q``
and a radius ``Δ`` [rad], proposes a step ``δ`` (shape ``(N−1, nv)``: the first sample is
fixed) with the decrease its model predicts, ``pred = φ(Q) − model(δ)``. The driver
(:func:`minimise`) owns everything else, after scipy's ``optimize/_trustregion.py``:

* the trial ``Q⁺ = Π(Q + δ)`` (projected onto the position and speed limits exactly, so
  every iterate is feasible) and the ratio :math:`\rho = (\varphi(Q) - \varphi(Q^+))/pred`;
* acceptance: :math:`\rho >` :data:`ACCEPT_RATIO` and :math:`\varphi(Q^+) < \varphi(Q)`;
  the radius then grows to ``min(2Δ, Δ_max)`` when :math:`\rho >` :data:`GROW_RATIO` and
  ``‖δ‖_∞ > 0.9 Δ``; a rejected step shrinks it to ``¼ min(Δ, ‖δ‖_∞)``, and below
  ``Δ_min`` the loop stops;
* the stop tests (:class:`Stopping`): converged (the subproblem's stationarity test, or
  ``‖δ‖_∞ ≤`` a step tolerance), no predicted decrease (``pred ≤ r·φ + a``), the iteration
  cap, the deadline (stop, or raise :class:`~otmm_qp.exceptions.TimeBudgetExceeded`), a
  settled merit, a certificate reached (a few more iterations only), a stall
  (:func:`stalled`).

The best iterate by ``max m`` (the largest merit [tolerances], what a label depends on) and
the last accepted one are both returned (:class:`Outcome`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import NamedTuple, Protocol

import numpy as np

from otmm_qp.exceptions import TimeBudgetExceeded
from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.reference.projection import project_path
from otmm_qp.robots.robot import FloatArray

#: A step is accepted when the actual decrease exceeds this fraction of the predicted one.
ACCEPT_RATIO = 0.1
#: The radius grows after a step this good that used at least :data:`EDGE` of the radius.
GROW_RATIO = 0.75
EDGE = 0.9
#: Radius factors: growth after a good step, shrink (of ``min(Δ, ‖δ‖∞)``) after a rejected one.
GROW = 2.0
SHRINK = 0.25
#: Accepted steps over which progress is measured for the stall test.
STALL_WINDOW = 3
#: Relative gain over that window below which the solve has stalled [-].
STALL_GAIN = 1e-2


class Iterate(NamedTuple):
    """A feasible path with its evaluation.

    Attributes:
        path: Joint path ``(N, nv)``.
        errors: Its task errors ``(N, n)`` [m, rad].
        merits: Its merits [tolerances] (the subproblem's shape; ``top`` is their largest).
        phi: The merit function ``φ`` the steps decrease (the subproblem's units).
    """

    path: FloatArray
    errors: FloatArray
    merits: FloatArray
    phi: float

    @property
    def top(self) -> float:
        """``max m`` [tolerances]."""
        return float(np.max(self.merits))


class Step(NamedTuple):
    """A subproblem's proposal.

    Attributes:
        delta: The step ``δ`` of samples ``1..N−1``, shape ``(N−1, nv)`` [rad or m].
        predicted: The model's predicted decrease of ``φ`` (``φ(Q) − model(δ)``).
        kkt: The subproblem's KKT residual at ``δ = 0`` (NaN when it has none).
        stationary: Whether the subproblem certifies ``δ = 0`` stationary (converged).
    """

    delta: FloatArray
    predicted: float
    kkt: float = math.nan
    stationary: bool = False


class Subproblem(Protocol):
    """What the driver needs of a method: its task, its evaluation and its step."""

    problem: TrackingProblem

    def start(self, path: FloatArray) -> Iterate:
        """The first iterate (a subproblem may prepare its model there)."""
        ...

    def evaluate(self, path: FloatArray) -> Iterate:
        """A trial path's iterate."""
        ...

    def step(self, iterate: Iterate, radius: float) -> Step:
        """The step at ``iterate`` within ``‖δ‖_∞ ≤ radius`` [rad]."""
        ...


@dataclass(frozen=True)
class Radii:
    """Trust radii of one method [rad]: first, largest, smallest (below it the loop stops)."""

    initial: float
    largest: float
    smallest: float


@dataclass(frozen=True)
class Stopping:
    """The stop tests a method uses besides the cap, the ratio and the radius floor.

    Attributes:
        step_tolerance: Converged when ``‖δ‖_∞ ≤`` this [rad].
        relative_decrease: Stop when ``pred ≤ relative_decrease · φ + absolute_decrease``.
        absolute_decrease: See ``relative_decrease`` (``φ``'s units).
        settle: Stop once an accepted iterate has ``max m ≤ settle`` (None: never).
        after_certificate: Iterations still allowed once an accepted iterate has
            ``max m ≤ 1`` (None: no limit).
        stall: Stop when the accepted steps crawl (:func:`stalled`).
        raise_at_deadline: Raise :class:`~otmm_qp.exceptions.TimeBudgetExceeded` at the
            deadline (else stop with the best iterate so far).
    """

    step_tolerance: float = 0.0
    relative_decrease: float = 0.0
    absolute_decrease: float = 0.0
    settle: float | None = None
    after_certificate: int | None = None
    stall: bool = False
    raise_at_deadline: bool = False


@dataclass
class Outcome:
    """What one trust-region solve reached.

    Attributes:
        path: The iterate with the smallest ``max m`` found, shape ``(N, nv)``, within every
            limit.
        merit: Its ``max m`` [tolerances].
        step: ``‖δ‖_∞`` of the last subproblem [rad] (NaN when none ran).
        kkt: The last subproblem's KKT residual (NaN when none ran or it has none).
        iterations: Subproblems solved.
        converged: Stopped by the convergence test (not the cap, the deadline or a stall).
        current: The last accepted iterate's path (the smallest ``φ``; None: the start).
        radius: The trust radius [rad] the next subproblem would use.
    """

    path: FloatArray
    merit: float
    step: float = math.nan
    kkt: float = math.nan
    iterations: int = 0
    converged: bool = False
    current: FloatArray | None = None
    radius: float = math.nan


def stalled(history: list[float], remaining: int) -> bool:
    r"""Whether the solve has stalled: too slow to matter for any verdict.

    With ``m_j`` the merit after the ``j``-th accepted step and ``g`` the gain of the last
    :data:`STALL_WINDOW` of them: ``g < STALL_GAIN · m`` (a crawl), and crawling on at
    ``g / STALL_WINDOW`` per iteration for the ``remaining`` iterations cannot bring the
    merit to 1 (the tolerance: the only level a label depends on). A stalled stop is not
    converged (its convergence test is stored as it stands).
    """
    if len(history) <= STALL_WINDOW:
        return False
    merit = history[-1]
    gain = history[-1 - STALL_WINDOW] - merit
    return gain < STALL_GAIN * merit and merit - gain / STALL_WINDOW * remaining > 1.0


def trial(
    subproblem: Subproblem, current: Iterate, step: Step, radius: float, radii: Radii
) -> tuple[Iterate | None, float]:
    r"""Try ``current`` moved by ``step.delta`` (projected into the limits) as the next iterate.

    Returns:
        ``(accepted iterate or None, next radius)`` by the ratio test of the module docstring.
    """
    problem = subproblem.problem
    longest = float(np.max(np.abs(step.delta)))
    path = current.path.copy()
    path[1:] += step.delta
    path = project_path(path, problem.lower, problem.upper, problem.step)
    moved = subproblem.evaluate(path)
    ratio = (current.phi - moved.phi) / step.predicted
    if ratio > ACCEPT_RATIO and moved.phi < current.phi:
        if ratio > GROW_RATIO and longest > EDGE * radius:
            radius = min(GROW * radius, radii.largest)
        return moved, radius
    return None, SHRINK * min(radius, longest)


def minimise(
    subproblem: Subproblem,
    path: FloatArray,
    iterations: int,
    deadline: float,
    radii: Radii,
    stopping: Stopping,
    radius: float | None = None,
) -> Outcome:
    """Trust-region iterations of ``subproblem`` from a feasible ``path`` (module docstring).

    Args:
        subproblem: The method.
        path: Feasible start ``(N, nv)``.
        iterations: Cap on the subproblems solved.
        deadline: ``time.perf_counter()`` value past which no subproblem starts.
        radii: The method's radii.
        stopping: The method's stop tests.
        radius: First radius [rad] (None: ``radii.initial``), e.g. where a previous solve
            of the same task left it.

    Raises:
        TimeBudgetExceeded: At the deadline, when ``stopping.raise_at_deadline``.
    """
    current = subproblem.start(path)
    outcome = Outcome(path, current.top, radius=radii.initial if radius is None else radius)
    history = [outcome.merit]  # the best merit after every accepted step
    cap = iterations
    while outcome.iterations < cap:
        if time.perf_counter() > deadline:
            if stopping.raise_at_deadline:
                raise TimeBudgetExceeded("the reference's time budget ran out")
            break
        step = subproblem.step(current, outcome.radius)
        outcome.iterations += 1
        longest = float(np.max(np.abs(step.delta)))
        outcome.step, outcome.kkt = longest, step.kkt
        converged = step.stationary or longest <= stopping.step_tolerance
        floor = stopping.absolute_decrease
        if stopping.relative_decrease:  # (0 · inf would be NaN)
            floor = stopping.relative_decrease * current.phi + floor
        if converged or not step.predicted > floor:
            outcome.converged = converged
            break
        accepted, outcome.radius = trial(subproblem, current, step, outcome.radius, radii)
        if accepted is None:
            if outcome.radius < radii.smallest:
                break
            continue
        current = accepted
        outcome.current = current.path
        top = current.top
        if top < outcome.merit:
            outcome.path, outcome.merit = current.path, top
        if stopping.settle is not None and top <= stopping.settle:
            break
        if stopping.after_certificate is not None and top <= 1.0:
            cap = min(cap, outcome.iterations + stopping.after_certificate)
        history.append(outcome.merit)
        if stopping.stall and stalled(history, iterations - outcome.iterations):
            break
    return outcome
