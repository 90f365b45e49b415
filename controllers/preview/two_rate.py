r"""The two-rate scheme: the preview QP every ``N`` control steps, the one-step QP in between.

At the preview steps (``k mod N = 0``) the :class:`~.backend.PreviewBackend` QP is solved (its
nominal: the last plan advanced by ``N`` steps, :math:`\bar v = M^N v`) and its first velocity
executed; at the ``N − 1`` steps in between the project's one-step ``qp`` backend (same limits)
tracks the plan's knots: with the plan's displacement :math:`P(\tau)` from the joint
coordinates :math:`\theta_a` of the last preview step at :math:`t_a`, the command of step
``t`` is the Newton step to the plan's next point,

.. math:: \dot x_w = W\,e\big(x(\theta_a + P(t + dt - t_a)),\ x(\theta)\big) / dt,

one forward kinematics call and one small QP (usually its closed-form fast path). The
expensive QP thus runs at ``1/(N·dt)`` Hz (50 Hz for ``N = 10`` at dt = 2 ms).

Sliced (the default): the preview QP of the state at step ``k_s`` (``k_s`` every ``N`` steps)
is cut into slices of work (:meth:`~.backend.PreviewBackend.plan_slices`: the knots'
kinematics, the targets, the QP data, each fast-path candidate, the solver's update, its
solve) and one slice runs after the tracker in each control step, so no step pays for the
whole QP; the fast loop keeps tracking the previous plan until the new one is complete, then
switches (the plan is a function of time from ``t_a = k_s·dt``, so the switch needs no
re-timing). Every executed command is the tracker's; at the first step of an episode, with no
plan yet, the whole QP runs at once.
"""

from __future__ import annotations

from collections.abc import Generator, Sequence
from numbers import Integral, Real
from typing import ClassVar, NamedTuple

import numpy as np

from otmm_qp.backends.backend import BackendOutput
from otmm_qp.limits import LimitSpec
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.validation import Boolean, Constraints, Interval, check_params

from ..qp.backend import QpBackend
from .backend import PreviewBackend
from .parameters import InfeasiblePolicy, PeakScale, PreviewParameters

__all__ = ["TwoRatePreviewBackend"]


class TwoRatePreviewBackend(PreviewBackend):
    """``preview_two_rate``: :class:`PreviewBackend` every ``every`` steps, ``qp`` in between.

    Args:
        every: ``N``, control steps per preview QP, an integer ≥ 1 (1: the preview backend).
        tracker_regularization: μ of the tracking ``qp`` backend (> 0).
        sliced: Run the preview QP as slices of work, one per control step, starting every
            ``N`` steps (the plan it gives is tracked from the step after its last slice:
            a bounded step time); False: the whole QP in the step at ``k mod N = 0``.
            Ignored for ``every = 1`` (the preview backend).
        limits: The limits of both QPs (None: velocity and position, gain 0.5).
        horizon, knots, fine_steps, coarse_step, regularization, smoothness, jump,
        trust_region, solver, infeasible_policy, fast_path, peak, peak_jump, peak_scale: As
        :class:`PreviewBackend` (one :class:`~.parameters.PreviewParameters`, less
        ``working_set``).
    """

    name = "preview_two_rate"
    parameter_constraints: ClassVar[Constraints] = {
        **{k: v for k, v in PreviewBackend.parameter_constraints.items() if k != "working_set"},
        "every": Interval(Integral, 1, None, closed="left"),
        "tracker_regularization": Interval(Real, 0, None, closed="neither"),
        "sliced": Boolean(),
    }

    def __init__(
        self,
        *,
        every: int = 10,
        tracker_regularization: float = 1e-4,
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
        peak_scale: PeakScale = "absolute",
        sliced: bool = True,
    ) -> None:
        check_params(self, locals())
        self._configure(PreviewParameters.pick(locals()))  # every preview parameter, by name
        self.every = int(every)
        self.sliced = bool(sliced) and self.every > 1  # every = 1: the preview backend
        self.tracker = QpBackend(
            regularization=float(tracker_regularization),
            solver=self.parameters.solver,
            limits=list(self.limits.all),
            infeasible_policy=self.parameters.infeasible_policy,
        )

    def bind(self, robot: Robot, dt: float) -> None:
        """Bind both QPs; the preview's nominal advances ``N`` steps per solve."""
        super().bind(robot, dt)
        self._one_step = self._shift
        self._shifts = {self.every: np.linalg.matrix_power(self._one_step, self.every)}
        self._shift = self._shifts[self.every]
        self.tracker.bind(robot, dt)
        self._anchor: _Anchor | None = None
        self._job: _Job | None = None
        self._weight: FloatArray | None = None  # the task weight of the last state seen

    def reset(self) -> None:
        """Forget both QPs' warm starts and the plan."""
        super().reset()
        if hasattr(self.tracker, "robot"):
            self.tracker.reset()
        self._anchor = None
        self._job = None

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """The control step: ``qp`` tracking the plan; the preview QP as the module says.

        Not sliced: the preview QP at ``k mod N = 0`` (or with no plan yet), its ``v_1``
        executed. Sliced: the whole preview QP only at the first step (no plan yet); then
        every step is the tracker's, followed by one slice of the job that plans from the
        predicted switch time.
        """
        k = self._k
        t = k * self.dt
        if self._anchor is not None and t < self._anchor.start - 0.5 * self.dt:
            self._anchor = self._job = None  # the clock was set back (seek): start again
        if self._anchor is None or (not self.sliced and k % self.every == 0):
            output = super().solve(state, xdot, qdot_prev)
            robot = self.robot
            theta = state.q if robot.nq == robot.nv else robot.joint_coordinates(state.q)
            self._install(t, theta)
            return output
        self._k += 1
        if self.sliced:
            self._switch(t)
        output = self._track(t, state, qdot_prev)
        self.executed(output.qdot, qdot_prev)
        if self.sliced:
            self._advance_job(t, state, xdot)
        return output

    def _switch(self, t: float) -> None:
        """Track the finished job's plan from its switch time on."""
        job = self._job
        if job is not None and job.done and t >= job.switch - 0.5 * self.dt:
            self._install(job.switch, job.theta)
            self._job = None

    def _advance_job(self, t: float, state: KinematicState, xdot: FloatArray) -> None:
        """Run one slice of the job (starting one for the next switch time when none is on).

        The job plans from the state predicted at the switch time ``t_s = t_a + N·dt`` (later
        when the clock has passed it): the present joint coordinates θ moved as the tracked
        plan moves from now to then, ``θ + P(t_s − t_a) − P(t − t_a)`` (a lag of the tracker
        is kept, not assumed away), with ``q̇_prev = (P(t_s − t_a) − P(t_s − t_a − dt))/dt``;
        its nominal is the tracked plan advanced by ``(t_s − t_a)/dt`` steps.
        """
        job = self._job
        if job is None:
            anchor = self._anchor
            assert anchor is not None
            steps = max(self.every, int(round((t - anchor.start) / self.dt)) + 1)
            switch = anchor.start + steps * self.dt
            robot = self.robot
            now = state.q if robot.nq == robot.nv else robot.joint_coordinates(state.q)
            ahead = anchor.displacement(steps * self.dt) - anchor.displacement(t - anchor.start)
            theta = now + ahead
            qdot_prev = (
                anchor.displacement(steps * self.dt) - anchor.displacement((steps - 1) * self.dt)
            ) / self.dt
            state = KinematicState.compute(robot, robot.configuration(theta), self._weight)
            shift = self._shifts.get(steps)
            if shift is None:
                shift = self._shifts[steps] = np.linalg.matrix_power(self._one_step, steps)
            self._shift = shift
            slices = self.plan_slices(state, np.array(xdot), qdot_prev, switch)
            self._job = job = _Job(switch, theta, slices)
        if not job.done:
            try:
                next(job.slices)
            except StopIteration:
                job.done = True

    def _install(self, t: float, theta: FloatArray) -> None:
        """Track the plan just solved from ``θ`` [rad] at ``t`` [s]."""
        path = np.vstack([np.zeros(self.robot.nv), np.cumsum(
            self.grid.steps[:, None] * self._plan, axis=0
        )])  # fmt: skip
        self._anchor = _Anchor(t, np.array(theta), np.concatenate([[0.0], self.grid.taus]), path)

    def _track(self, t: float, state: KinematicState, qdot_prev: FloatArray) -> BackendOutput:
        """The ``qp`` step toward the plan's point at ``t + dt`` (module docstring)."""
        anchor = self._anchor
        assert anchor is not None
        self._weight = state.weight
        robot = self.robot
        point = anchor.theta + anchor.displacement(t + self.dt - anchor.start)
        target, _ = robot.kinematics(robot.configuration(point))
        command = state.weight * robot.task_error(target, state.x) / self.dt
        return self.tracker.solve(state, command, qdot_prev)


class _Anchor(NamedTuple):
    """A plan being tracked: from joint coordinates ``theta`` [rad] at time ``start`` [s].

    ``knots``: ``0, τ_1 … τ_K`` [s], shape ``(K + 1,)``; ``path``: the displacement ``P`` at
    them [rad], shape ``(K + 1, nv)``.
    """

    start: float
    theta: FloatArray
    knots: FloatArray
    path: FloatArray

    def displacement(self, tau: float) -> FloatArray:
        """``P(τ)`` [rad], shape ``(nv,)``: linear between knots, held outside ``[0, τ_K]``."""
        return np.array([np.interp(tau, self.knots, column) for column in self.path.T])


class _Job:
    """A preview solve in slices: its switch time [s], predicted ``θ`` [rad] and slices."""

    __slots__ = ("done", "slices", "switch", "theta")

    def __init__(
        self, switch: float, theta: FloatArray, slices: Generator[None, None, BackendOutput]
    ) -> None:
        self.switch, self.theta, self.slices, self.done = switch, theta, slices, False
