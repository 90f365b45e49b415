r"""The ``preview`` backend: one QP per control step over a horizon of the known future.

Each step (receding horizon): shift the last plan by one step into the nominal
(:meth:`~.knots.KnotGrid.shift_matrix`), linearise the task at every nominal knot
(:math:`\bar J_i`, :math:`\bar r_i`, :mod:`.targets`), solve the QP of :mod:`.formulation` in
the run's one warm-started solver session, execute the first segment's velocity ``v_1``
(clipped into the step's box of the project's limits) and keep the rest as the next nominal.

``preview`` reads the desired path ``x_d(t + τ)`` for ``τ ≤ H`` (information class
``preview H s``; a causal trajectory is refused before any compute);
``preview_causal`` (:class:`CausalPreviewBackend`) solves the same QP with the horizon filled
by holding the present command (information class ``causal``), so the two differ only in what
they know.
"""

from __future__ import annotations

import math
from collections.abc import Generator, Sequence
from typing import ClassVar, NamedTuple

import numpy as np

from otmm_qp.backends.backend import BackendOutput
from otmm_qp.exceptions import ParameterError
from otmm_qp.limits import AccelerationLimit, LimitSpec, PositionLimit, VelocityLimit, make_limits
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.status import Status
from otmm_qp.trajectories.preview import check_preview
from otmm_qp.trajectories.trajectory import Trajectory
from otmm_qp.validation import Constraints

from ..qp.box_backend import SOLVER_TOL, BoxQpBackend
from ..qp.formulation import clip_into_box
from ..qp.solvers import QpProblem, Solution
from .formulation import BoolArray, PreviewProblem, PreviewWeights
from .knots import KnotGrid
from .parameters import (
    POLICIES,
    PREVIEW_CONSTRAINTS,
    InfeasiblePolicy,
    PeakScale,
    PreviewParameters,
)
from .targets import HeldCommandTargets, Targets, TrajectoryTargets

__all__ = ["KNOTS_PER_SLICE", "CausalPreviewBackend", "PreviewBackend", "PreviewStep", "run_slices"]

#: Knots whose kinematics one slice of :meth:`PreviewBackend.plan_slices` computes.
KNOTS_PER_SLICE = 8


class PreviewStep(NamedTuple):
    """What one preview step solved (``BackendOutput.details``; buffers, copy to keep).

    Attributes:
        bounds: The step's box of ``v_1`` [rad/s], shape ``(2, nv)``.
        problem: The QP handed to the solver, or None (empty box).
        solution: The solver's answer, or None.
        plan: The plan's segment velocities [rad/s], shape ``(K, nv)`` (the solution, or the
            shifted nominal when there was none).
        taus: The knot offsets ``τ_1 … τ_K`` [s], shape ``(K,)``.
    """

    bounds: FloatArray
    problem: QpProblem | None
    solution: Solution | None
    plan: FloatArray
    taus: FloatArray


class PreviewBackend(BoxQpBackend):
    r"""Receding-horizon preview IK: the QP of :mod:`.formulation`, one per step.

    Args:
        horizon: ``H`` [s], > 0: how far ahead the desired path is read (and planned).
        knots: Cap ``K`` on the horizon's segments (move blocking), an integer ≥ 1.
        fine_steps: Segments of one control period ``dt`` at the start, an integer ≥ 1.
        coarse_step: Length Δ [s] of the later segments, a multiple of ``dt`` dividing
            ``H − fine·dt``; None: the most segments within ``knots``, each ≥ ``dt``.
        regularization: μ > 0 (the one-step QP's ``½μ‖q̇‖²``).
        smoothness: ρ ≥ 0, weight of the plan's second differences.
        jump: ρ₀ ≥ 0, weight of the executed step's velocity change ``‖v_1 − q̇_prev‖²``.
        trust_region: κ ≥ 0, weight of the distance to the nominal knots.
        peak: ω ≥ 0, weight of the plan's peak joint speed beyond the episode's executed peak
            (an epigraph variable and ``2·K·nv`` rows; 0: none).
        peak_jump: ω_a ≥ 0, weight of the plan's largest velocity change per step beyond the
            episode's executed one (an epigraph variable and ``2·K·nv`` rows; 0: none).
        peak_scale: ``absolute`` (``peak``, ``peak_jump`` are ω, ω_a) or ``arm`` (they are
            dimensionless and the weights follow the arm's speed limit and the window's task
            speed each step: :math:`\omega = \hat\omega\,\bar v^2/\dot q_{lim}`,
            :mod:`.parameters`).
        solver: ``daqp``, ``proxsuite``, ``osqp`` (persistent sessions, warm started) or
            another installed qpsolvers backend.
        limits: The project's limits (:mod:`otmm_qp.limits`): the first segment keeps their
            box; the later ones the speed limit (a ``velocity`` entry's ``max_speed`` caps
            it), the position box when a ``position`` limit is listed (default) and the
            acceleration limit when one is listed. A soft ``command`` limit (the command's
            acceleration and jerk) shapes the first segment's box, braking first (status
            ``relaxed`` when given up; a QP it leaves without solution brakes instead of
            failing). None: velocity and position (gain 0.5).
        infeasible_policy: ``raise``, ``hold`` or ``dls`` (the nominal's first velocity
            clipped into the relaxed box), as the ``qp`` backend.
        fast_path: Skip the solver when the last step's active bounds, or none, give a point
            meeting the KKT conditions (one Cholesky) — then it is the QP's optimum.
        working_set: Keep the last optimum's active rows too (the same QP, the same optimum,
            less work): the fast path tries the whole active set, bounds and rows
            (:meth:`PreviewProblem.with_active_set`), and the solver sees only the working
            rows — those active at the last optimum and those the nominal breaks — adding the
            rows its answer breaks until it breaks none (then it is the whole QP's optimum:
            a relaxation's optimum that meets every row).

    Raises:
        ParameterError: A parameter out of range (at construction), or a knot layout that
            does not fit ``dt`` (at :meth:`bind`: ``H < dt``, a ``coarse_step`` that is not
            a multiple of ``dt`` or does not divide the rest, more knots than the cap).
        PreviewUnavailable: At :meth:`attach`, a trajectory known less than ``H`` ahead.

    Every parameter is keyword-only and lands, checked, in one frozen
    :class:`~.parameters.PreviewParameters` (:attr:`parameters`).
    """

    name = "preview"
    policies = POLICIES
    parameter_constraints: ClassVar[Constraints] = PREVIEW_CONSTRAINTS

    def __init__(
        self,
        *,
        horizon: float = 1.0,
        knots: int = 16,
        fine_steps: int = 4,
        coarse_step: float | None = None,
        regularization: float = 1e-4,
        smoothness: float = 0.001,
        jump: float = 0.0,
        trust_region: float = 1e-3,
        solver: str = "daqp",
        limits: Sequence[LimitSpec] | None = None,
        infeasible_policy: InfeasiblePolicy = "raise",
        fast_path: bool = True,
        peak: float = 0.0,
        peak_jump: float = 0.0,
        working_set: bool = False,
        peak_scale: PeakScale = "absolute",
    ) -> None:
        self._configure(PreviewParameters.pick(locals()))

    def _configure(self, parameters: PreviewParameters) -> None:
        """Keep the checked parameters (:attr:`parameters`); set up what they fix before bind."""
        p = self.parameters = parameters
        super().__init__(p.solver, make_limits(p.limits), p.infeasible_policy)
        self.fast_path = bool(p.fast_path)
        self.working_set = bool(p.working_set)
        self.horizon = float(p.horizon)
        self.knots = int(p.knots)
        self.fine_steps = int(p.fine_steps)
        self.coarse_step = None if p.coarse_step is None else float(p.coarse_step)
        self.peak_scale = p.peak_scale
        self.weights = PreviewWeights(
            float(p.regularization), float(p.smoothness), float(p.jump), float(p.trust_region),
            float(p.peak), float(p.peak_jump),
        )  # fmt: skip
        self._damping = float(np.sqrt(self.weights.regularization))
        self._targets: Targets | None = None
        self._trajectory: Trajectory | None = None

    @property
    def preview_horizon(self) -> float | None:
        """``H`` [s]: the backend reads ``x_d(t + τ)`` for ``τ ≤ H``."""
        return self.horizon

    def bind(self, robot: Robot, dt: float) -> None:
        """Lay out the knots for ``dt`` and allocate the QP (constant structure).

        Raises:
            ParameterError: The knot layout does not fit ``dt`` (see the class docstring).
        """
        self.grid = KnotGrid.layout(self.horizon, dt, self.fine_steps, self.knots, self.coarse_step)
        KnotGrid.check_memory(self.grid.count, robot.nv)  # before anything (K·n)² is allocated
        self._shift = self.grid.shift_matrix()
        self._taus, self._steps = self.grid.taus, self.grid.steps[:, None]
        nv, count = robot.nv, self.grid.count
        boxes = self.limits.boxes
        position = any(isinstance(limit, PositionLimit) for limit in boxes)
        acceleration = None
        for limit in boxes:
            if isinstance(limit, AccelerationLimit):
                limit.bind(robot, dt)
                step = limit.step / dt
                acceleration = step if acceleration is None else np.minimum(acceleration, step)
        self._qp = PreviewProblem(self.grid, nv, self.weights, position, acceleration)
        self._theta_limits = np.array(robot.position_limits, dtype=float).reshape(2, nv)
        self._jacobians = np.empty((count, robot.task_dim, nv))
        self._residuals = np.empty((count, robot.task_dim))
        self._plan = np.zeros((count, nv))
        super().bind(robot, dt)
        speed = np.full(nv, np.inf)
        for limit in boxes:
            if isinstance(limit, VelocityLimit):
                speed = np.minimum(speed, limit.speed)
        self._speed = speed
        # q̇_lim of the ``arm`` peak weights: the arm's slowest joint (its model, capped).
        slowest = float(np.min(np.minimum(np.asarray(robot.velocity_limits, dtype=float), speed)))
        self._slowest_joint = slowest if math.isfinite(slowest) and slowest > 0.0 else 1.0
        self._targets = self._make_targets(self._trajectory)

    def attach(self, trajectory: Trajectory) -> None:
        """Keep the run's desired path, refusing one known less than ``H`` ahead.

        Raises:
            PreviewUnavailable: ``trajectory.lookahead < H``.
        """
        check_preview(trajectory, self.preview_horizon, "horizon")
        self._trajectory = trajectory
        if hasattr(self, "grid"):
            self._targets = self._make_targets(trajectory)

    def _make_targets(self, trajectory: Trajectory | None) -> Targets | None:
        """The preview's targets: the trajectory's window (None until one is attached)."""
        return None if trajectory is None else TrajectoryTargets(trajectory, self.grid.taus)

    def reset(self) -> None:
        """Forget the plan, the clock, the active-set guess and the solver's warm start."""
        super().reset()
        self._k = 0
        self._active: tuple[BoolArray, BoolArray] | None = None
        self._working: ActiveSet | None = None
        self._peak = 0.0
        self._peak_jump = 0.0
        self._task_speed = 0.0
        if hasattr(self, "_plan"):
            self._plan[:] = 0.0

    def seek(self, t: float) -> None:
        """Set the clock: the next solve is the step at ``t`` [s] (a replay that skips steps)."""
        self._k = int(round(t / self.dt))

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """``q̇ = v_1`` [rad/s], shape ``(nv,)``, within the step's box; details a PreviewStep.

        The k-th call after :meth:`reset` is the step at ``t = k·dt`` (as the loop runs it):
        :meth:`plan_slices` run to the end.

        Raises:
            ParameterError: No trajectory was attached to a ``preview`` backend.
            NonFiniteState: The desired path is NaN or inf inside the window.
            InfeasibleProblem: No solution under the ``raise`` policy.
        """
        t = self._k * self.dt
        self._k += 1
        output = run_slices(self.plan_slices(state, xdot, qdot_prev, t))
        self.executed(output.qdot, qdot_prev)
        return output

    def executed(self, qdot: FloatArray, qdot_prev: FloatArray) -> None:
        """Keep the episode's peak speed and jump [rad/s] (the floors of the epigraph terms)."""
        self._peak = max(self._peak, float(np.abs(qdot).max()))
        self._peak_jump = max(self._peak_jump, float(np.abs(qdot - qdot_prev).max()))

    def plan_slices(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray, t: float
    ) -> Generator[None, None, BackendOutput]:
        """One preview solve at time ``t`` [s] as slices of work, yielding between slices.

        The slices: the box and the nominal; the knots' kinematics, :data:`KNOTS_PER_SLICE`
        at a time; the targets; the QP's data; each fast-path candidate; the solver's update;
        its solve and the new plan. A caller may run them across several control steps
        (the two-rate scheme) or at once (:func:`run_slices`). ``state``, ``xdot`` and
        ``qdot_prev`` must stay unchanged until the last slice. Returns the step's output
        (``q̇ = v_1``); the plan is :attr:`_plan` from then on.

        Raises:
            As :meth:`solve`, from the slice that meets the condition.
        """
        targets = self._targets
        if targets is None:
            raise ParameterError(
                "horizon", "a preview backend needs the run's trajectory (Controller.bind)"
            )
        theta, empty = self.begin_step(state, qdot_prev)
        plan = self._shift @ self._plan  # the nominal: the last plan advanced
        taus = self._taus
        if empty:
            detail = self.box.conflict(self.robot.joint_names)
            qdot, status = self.fallback(detail, (None, None), True, plan[0])
            self._plan = plan
            return self._output(qdot, status, None, None, plan, taus)
        bounds = self.box.bounds
        nominal = np.add.accumulate(self._steps * plan)  # d̄_i, (K, nv): cumsum over knots
        for start in range(0, self.grid.count, KNOTS_PER_SLICE):
            yield
            knots = self._linearise(state, theta, nominal, start)
            yield
            targets.residuals(self.robot, state, xdot, t, knots, self._residuals, start)
        yield
        room = self._theta_limits - theta
        scale = None
        if self.peak_scale == "arm":  # ω = ω̂ v̄²/q̇_lim, v̄ the episode's fastest window so far
            speed = targets.speed(self.robot, state, xdot, t)
            self._task_speed = max(self._task_speed, speed)
            scale = self._task_speed**2 / self._slowest_joint
        problem = self._qp.build(
            self._jacobians, self._residuals, nominal, qdot_prev, bounds,
            self._speed, room, self._peak, self._peak_jump, scale,
        )  # fmt: skip
        if self.working_set:
            floors = (self._peak, self._peak_jump)[: problem.q.shape[0] - plan.size]
            solution = yield from self._solve_working_set(
                problem, np.concatenate([plan.reshape(-1), floors])
            )
        else:
            solution = yield from self._solve(problem)
        settled = None if solution.x is None else clip_into_box(
            solution.x[: self.robot.nv], bounds, SOLVER_TOL
        )  # fmt: skip
        if settled is None or solution.x is None:
            detail = f"solver {self.solver!r} found no solution ({solution.detail})"
            if self.box.has_soft:  # the command box's point may leave the plan no room: brake
                qdot, status = self.brake()
            else:
                qdot, status = self.fallback(detail, (problem.copy(), solution), False, plan[0])
            self._plan = plan
            return self._output(qdot, status, problem, solution, plan, taus)
        qdot, active = settled
        self._plan = plan  # same shape: the buffer takes the solution
        np.copyto(plan, solution.x[: plan.size].reshape(plan.shape))
        plan[0] = qdot
        status = Status.BOUNDED if active else Status.OK
        if self.box.softened:
            status = Status.RELAXED
        return self._output(qdot, status, problem, solution, self._plan, taus)

    def _solve(self, problem: QpProblem) -> Generator[None, None, Solution]:
        """The fast paths, else the session; one slice per attempt.

        First the last step's active bounds advanced by one segment, as the plan is, then as
        they were (:meth:`PreviewProblem.with_active_bounds`, KKT conditions checked), then
        the unconstrained minimiser; the solver only when none is the optimum. The active
        bounds of whatever is accepted are the next guess.
        """
        qp = self._qp
        if self.fast_path:
            guess = self._active
            if guess is not None and (guess[0].any() or guess[1].any()):
                nv = self.robot.nv
                plan = self._qp.grid.count * nv
                for candidate in (tuple(_advanced(mask, nv, plan) for mask in guess), guess):
                    yield
                    x = qp.with_active_bounds(*candidate)
                    if x is not None:
                        self._active = qp.active_bounds(x)
                        return Solution(x, True, "last active set optimal")
            yield
            x = qp.unconstrained()
            if x is not None:
                self._active = None
                return Solution(x, True, "unconstrained minimiser feasible")
        yield
        self.session.load(problem)
        yield
        solution = self.session.solve()
        if solution.x is not None:
            self._active = qp.active_bounds(solution.x)
        return solution

    def _solve_working_set(
        self, problem: QpProblem, nominal: FloatArray
    ) -> Generator[None, None, Solution]:
        """The ``working_set`` solve: the warm active set, else the solver on working rows.

        First the last optimum's active set (bounds and rows) advanced by one segment, then as
        it was, then the unconstrained minimiser (each KKT-checked, one slice each); else the
        session on the position rows and the rows active at the last optimum or broken by
        ``nominal`` (the shifted plan with the epigraph variables at their floors, shape
        ``(n,)``), adding the dropped
        rows its answer breaks (by more than ``SOLVER_TOL`` relative) and solving again until
        it breaks none. The active set of whatever is accepted is the next guess.
        """
        qp = self._qp
        guess = self._working
        if self.fast_path:
            if guess is not None:
                nv, plan = self.robot.nv, qp.grid.count * self.robot.nv
                advanced = ActiveSet(
                    _advanced(guess.lower, nv, plan),
                    _advanced(guess.upper, nv, plan),
                    qp.advance_rows(guess.rows_lower),
                    qp.advance_rows(guess.rows_upper),
                )
                for candidate in (advanced, guess):
                    yield
                    x = qp.with_active_set(*candidate)
                    if x is not None:
                        self._working = ActiveSet(*qp.active_bounds(x), *qp.active_rows(x))
                        return Solution(x, True, "last active set optimal")
            yield
            x = qp.unconstrained()
            if x is not None:
                self._working = None
                return Solution(x, True, "unconstrained minimiser feasible")
        rows = qp.violated_rows(nominal)
        rows[qp.position_rows] = True  # the hard limits; the epigraph rows are mostly slack
        if guess is not None:
            rows |= guess.rows_lower | guess.rows_upper
        while True:
            yield
            self.session.load(problem.with_rows(rows))
            yield
            solution = self.session.solve()
            if solution.x is None:
                return solution
            # Only dropped rows are added (the working rows are the solver's, met to its
            # tolerance): every pass adds one at least, so at most m passes.
            broken = qp.violated_rows(solution.x, SOLVER_TOL) & ~rows
            if not broken.any():
                break
            rows |= broken
        x = solution.x
        # The guess's bounds serve the fast path only; the working rows need the rows alone.
        lower, upper = qp.active_bounds(x) if self.fast_path else (_NONE, _NONE)
        self._working = ActiveSet(lower, upper, *qp.active_rows(x))
        return solution

    def _linearise(
        self,
        state: KinematicState,
        theta: FloatArray,
        nominal: FloatArray,
        start: int,
    ) -> list[FloatArray]:
        r"""Write :math:`\bar J_i = W J(\bar\theta_i)` of the next :data:`KNOTS_PER_SLICE` knots.

        Knots ``i ∈ [start, start + KNOTS_PER_SLICE)``; returns their task values.

        A knot at the present state (``d̄_i = 0``, e.g. every knot on the first step) reuses
        the state's Jacobian: no kinematics call.
        """
        robot, weight = self.robot, state.weight
        kinematics, configuration = robot.kinematics, robot.configuration
        euclidean = self._euclidean  # q = θ: no configuration call (as begin_step reads θ)
        knots: list[FloatArray] = []
        for i in range(start, min(start + KNOTS_PER_SLICE, self.grid.count)):
            offset = nominal[i]
            if not offset.any():
                knots.append(state.x)
                self._jacobians[i] = state.task_jacobian
                continue
            point = theta + offset
            x, jacobian = kinematics(point if euclidean else configuration(point))
            knots.append(x)
            np.multiply(weight[:, None], jacobian, out=self._jacobians[i])
        return knots

    def _output(
        self,
        qdot: FloatArray,
        status: Status,
        problem: QpProblem | None,
        solution: Solution | None,
        plan: FloatArray,
        taus: FloatArray,
    ) -> BackendOutput:
        record = PreviewStep(self.box.bounds, problem, solution, plan, taus)
        return BackendOutput(qdot, status, self._damping, details=record)


def run_slices(job: Generator[None, None, BackendOutput]) -> BackendOutput:
    """Run every slice of a :meth:`PreviewBackend.plan_slices` job; its output."""
    while True:
        try:
            next(job)
        except StopIteration as done:
            return done.value


#: An empty mask: the bounds of a working set kept without the fast path.
_NONE = np.zeros(0, dtype=bool)


class ActiveSet(NamedTuple):
    """An active set of the preview QP: bounds and rows held at each side (bool masks)."""

    lower: BoolArray
    upper: BoolArray
    rows_lower: BoolArray
    rows_upper: BoolArray


def _advanced(mask: BoolArray, nv: int, plan: int) -> BoolArray:
    """A per-variable mask advanced by one segment over the plan's ``plan = K·nv`` entries.

    The last segment is kept; entries after the plan (the peak variable) stay as they are.
    """
    moved = mask.copy()
    moved[: plan - nv] = mask[nv:plan]
    return moved


class CausalPreviewBackend(PreviewBackend):
    r"""The causal counterpart: the same QP, the horizon filled by holding the present command.

    The targets are :math:`\tau_i\dot x_w` from the present task value (:mod:`.targets`), so
    it runs on any trajectory and behind any filter; beside ``preview`` it shows what the
    preview itself buys. Parameters as :class:`PreviewBackend`.
    """

    name = "preview_causal"

    @property
    def preview_horizon(self) -> float | None:
        """None: causal (the horizon holds the present command, no future is read)."""
        return None

    def _make_targets(self, trajectory: Trajectory | None) -> Targets | None:
        """The held command (no trajectory needed)."""
        return HeldCommandTargets(self.grid.taus)
