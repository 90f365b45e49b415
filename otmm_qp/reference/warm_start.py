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
    column = scale[:, None]
    eye = np.eye(scale.shape[0])
    factor = RELATIVE_DAMPING**2
    lower, upper, most = problem.lower, problem.upper, problem.step
    minimum, maximum = np.minimum, np.maximum  # np.clip's values, cheaper on short rows
    for k in range(1, problem.samples):
        previous = path[k - 1]
        q = previous.copy()
        for _ in range(IK_ITERATIONS):
            error, jacobian = problem.kinematics.sample(q, k)
            error = scale * error
            scaled = column * jacobian
            gram = scaled @ scaled.T
            damping = factor * max(float(gram.trace()), 1e-12)
            move = scaled.T @ np.linalg.solve(gram + damping * eye, error)
            if not np.isfinite(move).all():
                break
            q = q + move
        step = minimum(maximum(q - previous, -most), most)
        path[k] = minimum(maximum(previous + step, lower), upper)
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
