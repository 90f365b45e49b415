r"""The solver's initial path: per-sample damped inverse kinematics within the limits."""

from __future__ import annotations

import numpy as np

from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.reference.projection import project_path
from otmm_qp.robots.robot import FloatArray

#: Damped Newton iterations per sample.
IK_ITERATIONS = 2
#: Damping λ relative to the largest singular value of ``S J``.
RELATIVE_DAMPING = 0.02


def damped_ik_path(problem: TrackingProblem) -> FloatArray:
    r"""Track each sample from the previous one with damped Newton steps, then limit them.

    .. math:: q \leftarrow q + \tilde J^\top (\tilde J \tilde J^\top + \lambda^2 I)^{-1}
              S\,e(x_d(t_k), f(q)), \qquad
              q_k = \Pi_{[l,u]}\big(q_{k-1} + \operatorname{clip}(q - q_{k-1}, -s, s)\big)

    with ``J̃ = S J`` and ``λ = 0.02 σ_max(J̃)`` (never singular). Every sample is inside the
    position limits and within a step ``s = v_max dt`` of the previous one.

    Returns:
        Joint path ``(N, nv)``, ``q_0`` first.
    """
    path = np.zeros((problem.samples, problem.nv))
    path[0] = problem.q0
    scale = problem.scale
    for k in range(1, problem.samples):
        q = path[k - 1].copy()
        for _ in range(IK_ITERATIONS):
            error, jacobian = problem.kinematics.sample(q, k)
            error = scale * error
            scaled = scale[:, None] * jacobian
            gram = scaled @ scaled.T
            damping = (RELATIVE_DAMPING**2) * max(float(np.trace(gram)), 1e-12)
            move = scaled.T @ np.linalg.solve(gram + damping * np.eye(gram.shape[0]), error)
            if not np.all(np.isfinite(move)):
                break
            q = q + move
        step = np.clip(q - path[k - 1], -problem.step, problem.step)
        path[k] = np.clip(path[k - 1] + step, problem.lower, problem.upper)
    return path


def joint_path_start(problem: TrackingProblem, trajectory: object) -> FloatArray | None:
    r"""The trajectory's own joint path, when it has one, projected onto the limits.

    A task built from a joint path (``joint_path``, ``random_reachable``: a
    :class:`~otmm_qp.trajectories.waypoints.JointWaypointsTrajectory`) is tracked exactly by
    ``q(t_k)``; starting there, the solver cannot miss that path for another IK branch.

    Returns:
        Joint path ``(N, nv)``, or None when the trajectory has no ``joint_sample``.
    """
    sample = getattr(trajectory, "joint_sample", None)
    if sample is None:
        return None
    path = np.array([np.asarray(sample(float(t))[0], dtype=float) for t in problem.times])
    if path.shape != (problem.samples, problem.nv) or not np.all(np.isfinite(path)):
        return None
    path[0] = problem.q0
    return project_path(path, problem.lower, problem.upper, problem.step)
