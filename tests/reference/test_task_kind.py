"""A task's kind does not depend on the study's rows (issue 40's regression).

Since "decided first" the reference keeps a controller's path whenever one meets every
tolerance; ``reference.near_singular`` (hence the kind *singular crossings*) is judged on the
task's own path instead (:func:`otmm_qp.reference.solve.task_path`: the better of the starts
computed from the task alone). A two-link arm reaching out to its full extension (a singular
pose) is solved twice: alone (the damped-IK start meets the tolerance and is kept), and with
a controller's path that tracks the target exactly, so that it is kept instead and comes
closer to the singularity (σ_min 0.0045 against the damped IK's 0.018; σ_S = 0.01 between).
Judged on the kept path, the two would disagree.
"""

from __future__ import annotations

import numpy as np

from otmm_qp.reference import ReferenceSettings, solve_reference
from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.reference.result import sigma_along
from otmm_qp.reference.solve import Candidate
from otmm_qp.reference.warm_start import damped_ik_path
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.trajectories.waypoints import WaypointsTrajectory

DT = 0.02
DURATION = 1.0
LINKS = (1.0, 0.8)
SIGMA_S = 0.01


def _exact(problem: TrackingProblem, q0: np.ndarray) -> np.ndarray:
    """The elbow-up two-link inverse kinematics of every target (``q_0`` kept exactly)."""
    first, second = LINKS
    path = []
    for target in problem.targets:
        x = np.asarray(target, dtype=float)[:2]
        cosine = (float(x @ x) - first**2 - second**2) / (2.0 * first * second)
        elbow = float(np.arccos(np.clip(cosine, -1.0, 1.0)))
        shoulder = np.arctan2(x[1], x[0]) - np.arctan2(
            second * np.sin(elbow), first + second * np.cos(elbow)
        )
        path.append([shoulder, elbow])
    out = np.array(path)
    out[0] = q0
    return out


def test_near_singular_and_the_kind_do_not_depend_on_the_rows() -> None:
    robot = PlanarArm(list(LINKS))
    q0 = np.array([0.2, 1.2])
    goal = sum(LINKS) * np.array([np.cos(0.5), np.sin(0.5)])  # full extension at the end
    trajectory = WaypointsTrajectory(robot.forward(q0), [goal.tolist()], duration=DURATION)
    settings = ReferenceSettings(position_tolerance=0.05, sigma_s=SIGMA_S)
    problem = TrackingProblem(robot, trajectory, q0, DT, DURATION, settings)
    exact = _exact(problem, q0)
    errors = problem.errors(exact)
    assert problem.limits.keeps(exact, errors)
    own = damped_ik_path(problem)
    own_sigma = float(np.min(sigma_along(robot, own, None)))
    assert float(np.max(problem.merits(problem.errors(own)))) <= 1.0  # the start is kept alone
    assert float(np.min(sigma_along(robot, exact, None))) < SIGMA_S < own_sigma
    offered = Candidate("exact", exact, errors, float(np.max(np.linalg.norm(errors, axis=1))))

    alone, _ = solve_reference(robot, trajectory, q0, DT, DURATION, settings)
    rows, _ = solve_reference(robot, trajectory, q0, DT, DURATION, settings, None, [offered])

    assert rows.bracket.source == "exact" and alone.bracket.source == "damped_ik"
    assert float(np.min(rows.sigma)) < SIGMA_S  # the kept paths differ on the judgement ...
    for name in ("reference.near_singular", "reference.min_sigma", "reference.achievable"):
        assert rows.columns()[name] == alone.columns()[name], name  # ... the task's do not
    assert rows.min_sigma == own_sigma and not rows.near_singular
    # the kind "singular crossings" (near_singular and achievable): the same on both
    assert rows.achievable and alone.achievable
