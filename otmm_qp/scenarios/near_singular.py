r"""``near_singular``: a task-space line or arc passing a singular pose at a drawn distance."""

from __future__ import annotations

import math
from collections.abc import Sequence
from numbers import Integral, Real
from typing import ClassVar, Literal

import numpy as np

from otmm_qp.exceptions import ParameterError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.scenarios.generator import (
    Task,
    TaskGenerationError,
    TaskGenerator,
    check_duration,
    check_range,
    draw,
)
from otmm_qp.scenarios.search import position_of, sigma_min_at, solve_ik, with_position
from otmm_qp.scenarios.singular import SingularSearch
from otmm_qp.trajectories.circle import CircleTrajectory
from otmm_qp.trajectories.pose import PoseCircleTrajectory
from otmm_qp.trajectories.trajectory import Trajectory
from otmm_qp.trajectories.waypoints import WaypointsTrajectory
from otmm_qp.validation import ArrayOf, Constraints, InstanceOf, Interval, check_params

SHAPES = ("line", "arc")
#: Singular poses tried (each with ``attempts`` path draws) before giving up. A task drawn
#: within fewer poses is the same for any value (the draws are taken in order), so raising it
#: only adds tasks that would fail: at 3, 4 of the Panda's 400 ``arms.yaml`` tasks did.
SINGULAR_POSES = 10


def _unit(rng: np.random.Generator, dim: int) -> FloatArray:
    v = rng.normal(size=dim)
    return np.asarray(v / np.linalg.norm(v), dtype=float)


def _perpendicular(rng: np.random.Generator, a: FloatArray) -> FloatArray:
    """Random unit vector orthogonal to unit ``a`` (2-D: one of the two normals)."""
    if a.size == 2:
        return np.array([-a[1], a[0]]) * (1.0 if rng.random() < 0.5 else -1.0)
    v = rng.normal(size=3)
    v -= (v @ a) * a
    return np.asarray(v / np.linalg.norm(v), dtype=float)


class NearSingularGenerator(TaskGenerator):
    r"""Pass a singular pose at closest-approach distance ``d`` (a study variable).

    1. Find ``q_s`` with σ_min(q_s) < ``sigma_tolerance`` (random starts, Newton descent on
       σ_min with :func:`~otmm_qp.singularity.sigma_min_gradient`); ``p_s = f(q_s)``.
    2. Draw ``d``, a unit direction ``a`` and a unit ``b ⊥ a``; the closest point is
       ``c = p_s + d b``.
    3. ``line``: from ``c − (L/2)a`` to ``c + (L/2)a`` (one quintic segment, so the speed is
       highest at ``c``). ``arc``: the circle of radius ``R`` with centre ``c + R b`` through
       ``c`` (tangent ``a``), arc length ``L`` centred on ``c``: its distance to ``p_s`` is
       ``‖p_s − o‖ − R = d`` at ``c``.
    4. ``q0``: damped IK from ``q_s`` to the start (pose tasks keep ``q_s``'s orientation,
       held constant along the path).

    Descriptors: ``closest_distance`` ``d`` [m], ``sigma_min_singular`` σ_min(q_s),
    ``sigma_min_closest`` σ_min at the IK solution of ``c`` nearest ``q_s``, ``shape``,
    ``path_length`` ``L`` [m].

    Args:
        distance: ``[low, high]`` of ``d`` [m].
        length: ``[low, high]`` of ``L`` [m].
        duration: ``[low, high]`` of the motion time [s].
        shapes: Shapes drawn from (``line``, ``arc``).
        arc_radius: ``[low, high]`` of ``R`` [m] for arcs.
        sigma_tolerance: σ_min below which a configuration counts as singular.
        restarts: Random starts of the singular search.
        iterations: Descent iterations per start.
        attempts: Draws of path and start before giving up (unreachable starts are redrawn).
    """

    name = "near_singular"

    parameter_constraints: ClassVar[Constraints] = {
        "distance": ArrayOf(
            Interval(Real, 0, None, closed="left", unit="m"), length=2, per="end of [low, high]"
        ),
        "length": ArrayOf(
            Interval(Real, 0, None, closed="neither", unit="m"), length=2, per="end of [low, high]"
        ),
        "duration": ArrayOf(
            Interval(Real, 0, None, closed="neither", unit="s"), length=2, per="end of [low, high]"
        ),
        "shapes": InstanceOf(
            (list, tuple), "a list of shapes: " + ", ".join(SHAPES), exclude=(str,)
        ),
        "arc_radius": ArrayOf(
            Interval(Real, 0, None, closed="neither", unit="m"), length=2, per="end of [low, high]"
        ),
        "sigma_tolerance": Interval(Real, 0, None, closed="neither"),
        "restarts": Interval(Integral, 1, None),
        "iterations": Interval(Integral, 1, None),
        "attempts": Interval(Integral, 1, None),
    }

    def __init__(
        self,
        distance: Sequence[float] = (0.0, 0.05),
        length: Sequence[float] = (0.2, 0.4),
        duration: Sequence[float] = (2.0, 3.0),
        shapes: Sequence[str] = SHAPES,
        arc_radius: Sequence[float] = (0.2, 0.5),
        sigma_tolerance: float = 1e-3,
        restarts: int = 20,
        iterations: int = 100,
        attempts: int = 10,
    ) -> None:
        check_params(self, locals())
        self.distance = check_range("distance", distance)
        self.length = check_range("length", length)
        if not self.length[0] > 0.0:
            raise ParameterError("length", f"must be > 0 [m], got {list(length)}")
        self.duration = check_duration(duration)
        self.arc_radius = check_range("arc_radius", arc_radius)
        if not self.arc_radius[0] > 0.0:
            raise ParameterError("arc_radius", f"must be > 0 [m], got {list(arc_radius)}")
        self.shapes = tuple(shapes)
        unknown = [s for s in self.shapes if s not in SHAPES]
        if not self.shapes or unknown:
            raise ParameterError("shapes", f"allowed: {', '.join(SHAPES)}; got {list(shapes)}")
        self.search = SingularSearch(sigma_tolerance, restarts, iterations)
        if int(attempts) < 1:
            raise ParameterError("attempts", f"must be >= 1, got {attempts}")
        self.attempts = int(attempts)

    def generate(self, robot: Robot, seed: int, task_weight: FloatArray | None = None) -> Task:
        """Draw the task of ``seed`` (see the class docstring)."""
        rng = np.random.default_rng(seed)
        for _ in range(SINGULAR_POSES):
            task = self._try_pose(robot, rng, task_weight)
            if task is not None:
                return task
        raise TaskGenerationError(
            self.name,
            robot.name,
            f"no reachable path start within {SINGULAR_POSES} singular poses x "
            f"{self.attempts} attempts",
        )

    def _try_pose(
        self, robot: Robot, rng: np.random.Generator, task_weight: FloatArray | None
    ) -> Task | None:
        """One singular pose and up to ``attempts`` paths past it; None if none is reachable."""
        q_s = self.search.find(robot, rng, self.name, task_weight)
        x_s = robot.forward(robot.configuration(q_s))
        p_s = position_of(x_s)
        for _ in range(self.attempts):
            d = draw(rng, self.distance)
            length = draw(rng, self.length)
            duration = draw(rng, self.duration)
            shape = str(self.shapes[int(rng.integers(len(self.shapes)))])
            a = _unit(rng, p_s.size)
            b = _perpendicular(rng, a)
            closest = p_s + d * b
            radius = draw(rng, self.arc_radius) if shape == "arc" else math.inf
            if shape == "line":
                begin = closest - 0.5 * length * a
            else:
                centre = closest + radius * b
                half = 0.5 * length / radius  # half the swept angle [rad]
                begin = centre - radius * (math.cos(half) * b + math.sin(half) * a)
            q0 = solve_ik(robot, q_s, with_position(x_s, begin))
            q_c = solve_ik(robot, q_s, with_position(x_s, closest))
            if q0 is None or q_c is None:
                continue
            start = robot.forward(robot.configuration(q0))
            trajectory: Trajectory
            if shape == "line":
                trajectory = WaypointsTrajectory(
                    start, [list(closest + 0.5 * length * a)], duration=duration
                )
            else:
                trajectory = self._arc(start, centre, radius, a, b, length, duration)
            descriptors: dict[str, float | int | str] = {
                "closest_distance": d,
                "sigma_min_singular": sigma_min_at(robot, q_s, task_weight),
                "sigma_min_closest": sigma_min_at(robot, q_c, task_weight),
                "sigma_min_start": sigma_min_at(robot, q0, task_weight),
                "shape": shape,
                "path_length": length,
                "singular_x": float(p_s[0]),
                "singular_y": float(p_s[1]),
                "singular_z": float(p_s[2]) if p_s.size == 3 else 0.0,
            }
            return Task(q0, trajectory, trajectory.duration, descriptors)
        return None

    @staticmethod
    def _arc(
        start: FloatArray,
        centre: FloatArray,
        radius: float,
        a: FloatArray,
        b: FloatArray,
        length: float,
        duration: float,
    ) -> Trajectory:
        """Arc of length ``length`` through ``c = centre − R b`` with tangent ``a`` there."""
        turns = length / (2.0 * math.pi * radius)
        period = duration / turns
        if centre.size == 2:
            # Counterclockwise in the x-y plane moves along +a at c iff (−b) × a > 0.
            cross = -(b[0] * a[1] - b[1] * a[0])
            direction: Literal["clockwise", "counterclockwise"] = (
                "counterclockwise" if cross > 0.0 else "clockwise"
            )
            return CircleTrajectory(
                start, list(centre), radius, period, direction, turns=turns, profile="quintic"
            )
        normal = np.cross(-b, a)  # counterclockwise about this normal moves along +a at c
        # Same arc either way; a pose start also carries its orientation along.
        arc = PoseCircleTrajectory if np.asarray(start).ndim == 2 else CircleTrajectory
        return arc(
            start,
            list(centre),
            radius,
            period,
            "counterclockwise",
            normal=list(normal),
            turns=turns,
            profile="quintic",
        )
