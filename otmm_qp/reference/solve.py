r"""The offline reference of one task: a certified bracket ``lower ≤ min-max ≤ upper``.

The solver sees the whole desired path ``x_d(t_k)``, ``k = 0..N−1``, and brackets

.. math::
    \min_{q_1..q_{N-1}} \max_k m_k(q_k) \quad\text{s.t.}\quad l \le q_k \le u,\quad
    |q_k - q_{k-1}| \le v_{max}\,dt,\quad q_0 \text{ given},

``m_k = max(‖e_pos,k‖/tol_pos, ‖e_rot,k‖/tol_rot)``. Every path it keeps is within every
limit:

1. **Starts**: per-sample damped IK (:func:`~otmm_qp.reference.warm_start.damped_ik_path`),
   the trajectory's own joint path when it has one, and the *candidates* — joint paths a
   controller ran on the task within every limit (:class:`Candidate`, with their own errors).
   **Decided first**: when a start (a controller's path included) already meets every
   tolerance, the task is ``achievable`` and nothing below is solved (its best start is the
   upper bound).
2. **Least squares** from the better of the task's own starts (damped IK, the joint path),
   then, unless a path already meets every tolerance, from the best controller path (both by
   merit, so the order of a study's controllers changes nothing,
   :func:`_least_squares_starts`): trust-region Newton with OSQP
   (:class:`~otmm_qp.reference.sqp.SequentialQP`) and Lawson re-weighting, as cheap good
   starts.
3. **Min-max polish** (only when no path meets every tolerance: an achievable task is
   decided, and a sharper upper bound would change no label and no success, which on an
   achievable task is judged by the tolerances): the epigraph SQP with second-order-cone
   subproblems (:class:`~otmm_qp.reference.conic.ConicEpigraph`:
   the error linearised, its norm exact) from the ``starts`` best distinct
   paths and ``perturbations`` seeded perturbations of the best, each to its convergence test
   (step and KKT residual, stored), its stall test (:func:`~otmm_qp.reference.trust_region.stalled`)
   or its cap (``polish_iterations`` for the best start, half of it for the others), within
   the time budget; it stops early once the bracket is closed (``upper − lower ≤ 1e-6
   upper``).
4. **Upper** = the smallest ``max_k m_k`` of every path above (so no known path within the
   limits beats it); **lower** = :func:`~otmm_qp.reference.bound.lower_bound`, raised on an
   undecided task by the per-sample branch and bound
   (:class:`~otmm_qp.reference.sample_bound.SampleSearch`) on its first ``SEARCH_SAMPLES``
   samples the best path misses, ``SEARCH_BOXES`` boxes each, then by the speed-coupled
   forward propagation (:func:`~otmm_qp.reference.coupled_bound.coupled_certificate`).
5. **Position optimum** (the one reference of claims about *position* error:
   oracle-relative error, trade-off): the smallest
   ``max_k ‖e_pos,k‖`` over every path above, polished by the cone epigraph solve on position alone
   (orientation free, ``polish_iterations / 2``) when it is above the position tolerance
   and more than ``POSITION_GAP`` (1 %) above its certified lower bound.
   Position tasks: the same path as the upper bound.

Label: ``achievable`` (a stored path meets every tolerance), ``unachievable`` (the lower
bound exceeds them: certified), ``undecided`` (neither); ``failed`` when a solver failed
and no certificate exists (``message`` says why). Running out of the time budget is not a
failure: the best path so far is the upper bound.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from otmm_qp.exceptions import SolverFailure, TimeBudgetExceeded
from otmm_qp.reference.bound import LowerBound, lower_bound
from otmm_qp.reference.chain import UnsupportedChain
from otmm_qp.reference.conic import ConicEpigraph
from otmm_qp.reference.coupled_bound import coupled_certificate
from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.reference.projection import project_path
from otmm_qp.reference.result import Bracket, ReferenceResult, ReferenceStatus, summarise
from otmm_qp.reference.sample_bound import SampleSearch
from otmm_qp.reference.settings import ReferenceSettings
from otmm_qp.reference.sqp import SequentialQP
from otmm_qp.reference.trust_region import Outcome
from otmm_qp.reference.warm_start import damped_ik_path, joint_path_start
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.trajectories.trajectory import Trajectory

#: Newton iterations per min-max round.
ROUND_ITERATIONS = 2
#: The least-squares phase stops once every error is below this fraction of its tolerance
#: (a certificate with margin; finer digits would not change any verdict).
SETTLE = 1e-2
#: Smallest Lawson weight (relative to the mean), so no sample is dropped for good.
WEIGHT_FLOOR = 1e-6
#: Relative gap ``(upper − lower)/upper`` below which no further start is tried [-].
GAP_TOLERANCE = 1e-6
#: Relative width ``(value − lower)/lower`` of the position optimum's certified bracket below
#: which it is not polished [-] (oracle-relative errors move by at most this fraction of it).
POSITION_GAP = 1e-2
#: Samples of an undecided task the per-sample branch and bound is tried on.
SEARCH_SAMPLES = 2
#: Boxes per sample of that search (a count, so the bound does not depend on the machine).
SEARCH_BOXES = 4000
#: Standard deviation of the seeded perturbation starts [rad].
PERTURBATION = 0.05


@dataclass(frozen=True)
class Candidate:
    """A known joint path on the task: a controller's run, with its own recorded errors.

    Attributes:
        name: Where it comes from (the controller's name).
        path: Joint coordinates ``(N, nv)`` at ``t_k = k dt`` [rad or m].
        errors: Its task errors ``(N, n)`` as recorded by the run [m, rad].
        max_error: Its ``max_error`` metric [m] (the row's value, so the reference's
            position optimum is never above it, to the last bit).
    """

    name: str
    path: FloatArray
    errors: FloatArray
    max_error: float


@dataclass
class _Path:
    """A path of the pool: its merit, errors, largest position error [m] and origin."""

    path: FloatArray
    errors: FloatArray
    merit: float
    position: float
    source: str


def admissible(problem: TrackingProblem, path: FloatArray, errors: FloatArray) -> bool:
    """Whether a candidate path keeps every limit the reference keeps (:mod:`.limits`)."""
    return problem.limits.keeps(path, errors)


def solve_reference(
    robot: Robot,
    trajectory: Trajectory,
    q0: FloatArray,
    dt: float,
    duration: float,
    settings: ReferenceSettings | None = None,
    task_weight: FloatArray | None = None,
    candidates: Sequence[Candidate] = (),
) -> tuple[ReferenceResult, TrackingProblem]:
    """The reference of a task (see the module docstring).

    Args:
        robot: The arm.
        trajectory: Desired motion.
        q0: Start joint coordinates ``(nv,)``, inside the position limits.
        dt: Sample period [s].
        duration: Horizon [s] (``max(1, round(duration/dt))`` samples, as a simulation).
        settings: Tolerances, speed cap and budget (defaults: :class:`ReferenceSettings`).
        task_weight: Task weight ``(n,)`` of the reported σ_min (None: identity).
        candidates: Known paths (controller runs); those not :func:`admissible` are ignored.

    Returns:
        ``(result, problem)``. A solver failure gives ``status = "failed"`` with the best
        path found so far; it never raises for it.

    Raises:
        NotWithinJointLimits: ``q0`` is outside the position limits (bad input).
        DimensionError: ``q0`` has the wrong length.
    """
    settings = settings or ReferenceSettings()
    tic = time.perf_counter()
    robot.check_start(q0)
    problem = TrackingProblem(robot, trajectory, q0, dt, duration, settings)
    deadline = tic + settings.time_budget
    bound = lower_bound(problem)
    pool, warm_merit = _starts(problem, trajectory, candidates)
    message: str | None = None
    polish = Outcome(pool[0].path, pool[0].merit)
    try:
        # decided by a known path (a start or a controller's): no solve needs to run
        if problem.samples > 1 and min(entry.merit for entry in pool) > 1.0:
            for start in _least_squares_starts(pool):
                if min(entry.merit for entry in pool) <= 1.0:
                    break  # decided: achievable
                _least_squares(problem, start, pool, deadline)
            if min(entry.merit for entry in pool) > 1.0:  # else decided: achievable
                polish = _polish(problem, pool, bound.value, deadline)
    except SolverFailure as error:
        message = f"solver failure: {error}"
    best = min(pool, key=lambda entry: entry.merit)
    position, position_lower = _position_optimum(problem, pool, bound, deadline)
    if best.merit > 1.0 and bound.value <= 1.0:
        bound = _search_samples(problem, best, bound)
    status: ReferenceStatus = _label(best.merit, bound.value)
    if message is not None and status != "achievable":
        status = "failed"
    elif message is None and time.perf_counter() > deadline:
        message = f"time budget of {settings.time_budget:g} s reached (best path so far kept)"
    bracket = Bracket(
        upper=best.merit,
        lower=bound.value,
        position_optimum=position,
        position_lower=position_lower,
        source=best.source,
        step=polish.step,
        kkt=polish.kkt,
        converged=polish.converged,
        iterations=polish.iterations,
        certificate=bound.certificate,
    )
    result = summarise(
        problem,
        best.path,
        task_weight,
        status,
        warm_merit,
        message,
        best.errors,
        bracket,
        task_path=task_path(pool),
    )
    result.seconds = time.perf_counter() - tic
    return result, problem


#: The starts computed from the task alone (no controller's path among them).
OWN_STARTS = ("damped_ik", "joint_path")


def task_path(pool: Sequence[_Path]) -> FloatArray:
    """The task's own path: the better of the starts computed from the task alone.

    Those starts: per-sample damped IK and the task's joint path when it has one; the better
    by ``max_k m_k`` (damped IK on a tie).

    Whether a task passes near a singularity (``reference.near_singular``, the kind *singular
    crossings*) is judged on it: it does not depend on which controllers' paths the study
    offers, unlike the path the reference keeps (a controller's, whenever one meets every
    tolerance).
    """
    return _own_best(pool).path


def _least_squares_starts(pool: Sequence[_Path]) -> list[_Path]:
    """The best of the task's own starts, then the best controller path when there is one.

    Both by merit, whatever the order of the candidates (the best of several equal merits: the
    first in the study's order, which only matters for exactly equal merits).
    """
    starts = [_own_best(pool)]
    known = [e for e in pool if e.source not in OWN_STARTS]
    if known:
        starts.append(min(known, key=lambda e: e.merit))
    return starts


def _own_best(pool: Sequence[_Path]) -> _Path:
    """The better of the starts computed from the task alone (damped IK on a tie)."""
    return min((e for e in pool if e.source in OWN_STARTS), key=lambda e: e.merit)


def _search_samples(problem: TrackingProblem, best: _Path, bound: LowerBound) -> LowerBound:
    """Raise the bound on an undecided task by the per-sample branch and bound.

    Tried on the first ``SEARCH_SAMPLES`` samples where the best path misses a tolerance
    (the earliest: their speed-reachable boxes are the smallest), ``SEARCH_BOXES`` boxes
    each, until one certifies ``m_k > 1``.
    """
    try:
        search = SampleSearch(problem)
    except UnsupportedChain:
        return bound
    missed = np.flatnonzero(problem.merits(best.errors) > 1.0)
    for sample in missed[missed > 0][:SEARCH_SAMPLES]:
        found = search.bound(int(sample), SEARCH_BOXES)
        bound = bound.raised(int(sample), found.merit, "search")
        if bound.value > 1.0:
            break
    return bound if bound.value > 1.0 else coupled_certificate(problem, bound)


def _label(upper: float, lower: float) -> ReferenceStatus:
    """``achievable`` (upper ≤ 1), ``unachievable`` (lower > 1) or ``undecided``."""
    if upper <= 1.0:
        return "achievable"
    return "unachievable" if lower > 1.0 else "undecided"


def _entry(problem: TrackingProblem, path: FloatArray, source: str) -> _Path:
    errors = problem.errors(path)
    return _Path(
        path,
        errors,
        float(np.max(problem.merits(errors))),
        float(np.max(np.linalg.norm(errors[:, : problem.linear], axis=1))),
        source,
    )


def _starts(
    problem: TrackingProblem, trajectory: Trajectory, candidates: Sequence[Candidate]
) -> tuple[list[_Path], float]:
    """The pool: damped IK, the joint path (if any), then the admissible candidates."""
    pool = [_entry(problem, damped_ik_path(problem), "damped_ik")]
    given = joint_path_start(problem, trajectory)
    if given is not None:
        pool.append(_entry(problem, given, "joint_path"))
    warm_merit = min(entry.merit for entry in pool)
    for candidate in candidates:
        errors = np.asarray(candidate.errors, dtype=float)
        if admissible(problem, candidate.path, errors):
            merit = float(np.max(problem.merits(errors)))
            path = np.array(candidate.path, dtype=float)
            pool.append(_Path(path, errors, merit, float(candidate.max_error), candidate.name))
    return pool, warm_merit


def _least_squares(
    problem: TrackingProblem, start: _Path, pool: list[_Path], deadline: float
) -> None:
    """Newton on the least squares, then Lawson rounds; every better path joins ``pool``."""
    settings = problem.settings
    sqp = SequentialQP(problem)
    weights = np.ones(problem.samples - 1)
    path = start.path
    try:
        path = sqp.improve(path, weights, settings.iterations, deadline, settle=SETTLE)
        entry = _entry(problem, path, "least_squares")
        pool.append(entry)
        for _ in range(settings.minimax_rounds if entry.merit > 1.0 else 0):
            merits = problem.merits(entry.errors)
            weights = weights * np.maximum(merits[1:], WEIGHT_FLOOR)
            weights = np.maximum(weights / np.mean(weights), WEIGHT_FLOOR)
            path = sqp.improve(path, weights, ROUND_ITERATIONS, deadline)
            entry = _entry(problem, path, "least_squares")
            pool.append(entry)
            if entry.merit <= 1.0:
                break
    except TimeBudgetExceeded:
        return


def _distinct(pool: list[_Path], count: int, key: str) -> list[_Path]:
    """The ``count`` best entries by ``key`` with pairwise different paths."""
    chosen: list[_Path] = []
    for entry in sorted(pool, key=lambda e: getattr(e, key)):
        if len(chosen) >= count:
            break
        if all(not np.array_equal(entry.path, other.path) for other in chosen):
            chosen.append(entry)
    return chosen


def _polish(problem: TrackingProblem, pool: list[_Path], lower: float, deadline: float) -> Outcome:
    """Cone epigraph solve from the best start, then from the next ones until the bracket closes.

    The next ones: the next best distinct starts and seeded perturbations of the best;
    every result joins ``pool``.

    Returns:
        The outcome of the solve that found the best path (its step and KKT residual).
    """
    settings = problem.settings
    solver = ConicEpigraph(problem)
    starts = [e.path for e in _distinct(pool, max(1, settings.starts), "merit")]
    rng = np.random.default_rng(settings.seed)
    for _ in range(settings.perturbations):
        noisy = starts[0] + rng.normal(0.0, PERTURBATION, starts[0].shape)
        noisy[0] = problem.q0
        starts.append(project_path(noisy, problem.lower, problem.upper, problem.step))
    perturbed = settings.perturbations
    outcomes: list[Outcome] = []
    for index, path in enumerate(starts):
        if time.perf_counter() > deadline:
            break
        if outcomes and _closed(min(o.merit for o in outcomes), lower):
            break  # certified optimal to GAP_TOLERANCE: another start cannot do better
        cap = settings.polish_iterations // (2 if index > 0 else 1)
        outcome = solver.solve(path, cap, deadline)
        outcomes.append(outcome)
        source = "epigraph" if index < len(starts) - perturbed else "perturbed"
        pool.append(_entry(problem, outcome.path, source))
    if not outcomes:
        return Outcome(pool[0].path, pool[0].merit)
    return min(outcomes, key=lambda o: o.merit)


def _closed(upper: float, lower: float) -> bool:
    """Whether ``upper − lower ≤ GAP_TOLERANCE · upper`` (the optimum is pinned)."""
    return upper - lower <= GAP_TOLERANCE * upper


def _position_optimum(
    problem: TrackingProblem, pool: list[_Path], bound: LowerBound, deadline: float
) -> tuple[float, float]:
    """Smallest largest position error [m] over the pool, polished on position alone.

    Not polished where no claim needs it: at or below the position tolerance, or when the
    certified bracket is already within :data:`POSITION_GAP` (``value ≤ (1 + gap) ·
    position_lower``: the polish could gain at most that fraction).
    """
    best = min(pool, key=lambda entry: entry.position)
    value = best.position
    settings = problem.settings
    tolerance = settings.position_tolerance
    alone = problem.pose and settings.orientation_tolerance is not None
    if not alone or problem.samples < 2 or tolerance is None or value <= tolerance:
        return value, bound.position_value
    if value <= (1.0 + POSITION_GAP) * bound.position_value:
        return value, bound.position_value
    if time.perf_counter() > deadline:
        return value, bound.position_value
    position = problem.position_only()
    try:
        cap = settings.polish_iterations // 2
        outcome = ConicEpigraph(position).solve(best.path, cap, deadline)
    except SolverFailure:
        return value, bound.position_value
    errors = problem.errors(outcome.path)
    polished = float(np.max(np.linalg.norm(errors[:, : problem.linear], axis=1)))
    return min(value, polished), bound.position_value
