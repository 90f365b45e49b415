"""``joint_path``: a straight joint-space path through or near a singular configuration."""

from __future__ import annotations

from collections.abc import Sequence
from numbers import Integral, Real
from typing import ClassVar

import numpy as np

from otmm_qp.exceptions import ParameterError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.scenarios.generator import Task, TaskGenerator, check_duration, check_range, draw
from otmm_qp.scenarios.search import clip_coordinates, sigma_min_at
from otmm_qp.scenarios.singular import SingularSearch
from otmm_qp.trajectories.waypoints import JointWaypointsTrajectory
from otmm_qp.validation import ArrayOf, Boolean, Constraints, Interval, check_params


class JointPathGenerator(TaskGenerator):
    r"""Joint path ``q_s + ε m + λ n``, ``λ ∈ [−Δ, Δ]``, its FK as the task reference.

    ``q_s`` is singular (see :class:`~otmm_qp.scenarios.singular.SingularSearch`), ``n`` and
    ``m ⊥ n`` are random unit joint directions, ``ε`` the drawn joint-space offset [rad] of
    the closest approach. Both ends are clipped into the joint limits.

    Descriptors: ``joint_offset`` ε [rad], ``sigma_min_singular``, ``sigma_min_closest``
    (σ_min at ``q_s + ε m``), ``half_span`` Δ [rad].

    Args:
        offset: ``[low, high]`` of ε [rad].
        half_span: ``[low, high]`` of Δ [rad].
        duration: ``[low, high]`` of the motion time [s].
        return_to_start: Come back along the same path.
        sigma_tolerance: σ_min below which a configuration counts as singular.
        restarts: Random starts of the singular search.
        iterations: Descent iterations per start.
    """

    name = "joint_path"

    parameter_constraints: ClassVar[Constraints] = {
        "offset": ArrayOf(
            Interval(Real, 0, None, closed="left", unit="rad"), length=2, per="end of [low, high]"
        ),
        "half_span": ArrayOf(
            Interval(Real, 0, None, closed="neither", unit="rad"),
            length=2,
            per="end of [low, high]",
        ),
        "duration": ArrayOf(
            Interval(Real, 0, None, closed="neither", unit="s"), length=2, per="end of [low, high]"
        ),
        "return_to_start": Boolean(),
        "sigma_tolerance": Interval(Real, 0, None, closed="neither"),
        "restarts": Interval(Integral, 1, None),
        "iterations": Interval(Integral, 1, None),
    }

    def __init__(
        self,
        offset: Sequence[float] = (0.0, 0.1),
        half_span: Sequence[float] = (0.3, 0.6),
        duration: Sequence[float] = (2.0, 3.0),
        return_to_start: bool = False,
        sigma_tolerance: float = 1e-3,
        restarts: int = 20,
        iterations: int = 100,
    ) -> None:
        check_params(self, locals())
        self.offset = check_range("offset", offset)
        self.half_span = check_range("half_span", half_span)
        if not self.half_span[0] > 0.0:
            raise ParameterError("half_span", f"must be > 0 [rad], got {list(half_span)}")
        self.duration = check_duration(duration)
        self.return_to_start = bool(return_to_start)
        self.search = SingularSearch(sigma_tolerance, restarts, iterations)

    def generate(self, robot: Robot, seed: int, task_weight: FloatArray | None = None) -> Task:
        """Draw the task of ``seed`` (see the class docstring)."""
        rng = np.random.default_rng(seed)
        q_s = self.search.find(robot, rng, self.name, task_weight)
        n = rng.normal(size=robot.nv)
        n /= np.linalg.norm(n)
        m = rng.normal(size=robot.nv)
        m -= (m @ n) * n
        m /= max(float(np.linalg.norm(m)), 1e-12)
        epsilon = draw(rng, self.offset)
        span = draw(rng, self.half_span)
        duration = draw(rng, self.duration)
        middle = clip_coordinates(robot, q_s + epsilon * m)
        q0 = clip_coordinates(robot, middle - span * n)
        q1 = clip_coordinates(robot, middle + span * n)
        start = robot.forward(robot.configuration(q0))
        trajectory = JointWaypointsTrajectory(
            start,
            robot,
            [list(q0), list(middle), list(q1)],
            segment_durations=[duration / 2.0, duration / 2.0],
            return_to_start=self.return_to_start,
        )
        descriptors: dict[str, float | int | str] = {
            "joint_offset": epsilon,
            "half_span": span,
            "sigma_min_singular": sigma_min_at(robot, q_s, task_weight),
            "sigma_min_closest": sigma_min_at(robot, middle, task_weight),
            "sigma_min_start": sigma_min_at(robot, q0, task_weight),
        }
        return Task(q0, trajectory, trajectory.duration, descriptors)
