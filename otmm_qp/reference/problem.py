r"""The tracking problem over the horizon: samples, scaled errors, limits and their linearisation.

Sample ``k = 0..N−1`` is at ``t_k = k·dt`` (the simulation's steps). The path is
``Q = (q_0, …, q_{N−1})``, shape ``(N, nv)`` in joint coordinates, with ``q_0`` fixed.
Errors are scaled by the tolerances, ``ẽ_k = S e(x_d(t_k), f(q_k))`` with
``S = diag(1/tol_pos, …, 1/tol_rot, …)``, so ``‖ẽ‖ ≈ 1`` is "at tolerance" in either part.
"""

from __future__ import annotations

import copy
import dataclasses
import math

import numpy as np

from otmm_qp.exceptions import DimensionError
from otmm_qp.reference.kinematics import SampleKinematics
from otmm_qp.reference.limits import PathLimits
from otmm_qp.reference.settings import ReferenceSettings
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.trajectories.trajectory import Trajectory

#: Scaled residual ‖S e_k‖ below which the curvature term is left out (it is proportional to
#: the residual, so Gauss–Newton is as good there and saves ``nv`` Jacobian derivatives).
CURVATURE_RESIDUAL = 0.05
#: Stand-in for an infinite bound in the QP (OSQP treats ≥ 1e30 as infinite).
BIG = 1e20


class TrackingProblem:
    r"""Everything about one task the reference solver needs, evaluated on demand.

    Args:
        robot: The arm.
        trajectory: Desired motion ``x_d(t)``.
        q0: Start joint coordinates, shape ``(nv,)``.
        dt: Sample period [s] (the study's control period).
        duration: Horizon [s]; ``N = max(1, round(duration/dt))`` samples.
        settings: Tolerances (scale ``S``; a pose task without an orientation tolerance
            scales its orientation rows by 0) and the speed cap.

    Attributes:
        targets: ``x_d(t_k)`` of every sample (length ``N``).
        scale: Diagonal of ``S``, shape ``(n,)``.
        lower, upper: Position limits [rad or m], shapes ``(nv,)`` (±inf: none).
        step: Largest joint step per sample ``v_max·dt`` [rad], shape ``(nv,)`` (inf: none).
        limits: The :class:`~otmm_qp.reference.limits.PathLimits` every path keeps.
    """

    def __init__(
        self,
        robot: Robot,
        trajectory: Trajectory,
        q0: FloatArray,
        dt: float,
        duration: float,
        settings: ReferenceSettings,
    ) -> None:
        self.robot = robot
        self.settings = settings
        self.dt = float(dt)
        self.q0 = np.asarray(q0, dtype=float).copy()
        self.samples = max(1, int(round(duration / dt)))
        self.times: FloatArray = np.arange(self.samples, dtype=float) * self.dt
        self.targets = [trajectory.sample(float(t))[0] for t in self.times]
        self.kinematics = SampleKinematics(robot, self.targets)
        n = robot.task_dim
        self.pose = robot.task_kind == "pose"
        self.linear = 3 if self.pose else n
        position = settings.position_tolerance
        orientation = settings.orientation_tolerance
        self.scale = np.ones(n) / (position if position is not None else 1.0)
        if self.pose:
            # A part without a tolerance is not in the merit: not in the least squares either.
            self.scale[3:] = 1.0 / orientation if orientation is not None else 0.0
        self.limits = PathLimits.of(robot, settings, self.q0, self.dt, duration)
        self.lower = self.limits.lower
        self.upper = self.limits.upper
        self.speed = self.limits.speed
        # Just inside the bound, so (q_{k+1} − q_k)/dt never reads above it after rounding.
        self.step = self.speed * self.dt * (1.0 - 1e-9)

    def position_only(self) -> TrackingProblem:
        """The same task with its merit on position alone (orientation free, scaled by 0)."""
        other = copy.copy(self)
        other.settings = dataclasses.replace(self.settings, orientation_tolerance=None)
        other.scale = self.scale.copy()
        if self.pose:
            other.scale[3:] = 0.0
        return other

    @property
    def nv(self) -> int:
        """Joint coordinates per sample."""
        return self.robot.nv

    def errors(self, path: FloatArray) -> FloatArray:
        """Unscaled task errors ``e(x_d(t_k), f(q_k))``, shape ``(N, n)``.

        Raises:
            DimensionError: ``path`` is not ``(N, nv)``.
        """
        if len(path) != self.samples:
            raise DimensionError("path", (self.samples, self.nv), np.shape(path))
        return self.kinematics.errors(np.asarray(path, dtype=float))

    def merits(self, errors: FloatArray) -> FloatArray:
        r"""Per-sample merit ``m_k = max(‖e_pos‖/tol_pos, ‖e_rot‖/tol_rot)``, shape ``(N,)``.

        A path meets every tolerance iff ``max_k m_k ≤ 1``; a part without a tolerance
        counts 0.
        """
        settings = self.settings
        merit = np.zeros(errors.shape[0])
        if settings.position_tolerance is not None:
            position = np.linalg.norm(errors[:, : self.linear], axis=1)
            merit = np.maximum(merit, position / settings.position_tolerance)
        if self.pose and settings.orientation_tolerance is not None:
            rotation = np.linalg.norm(errors[:, 3:], axis=1)
            merit = np.maximum(merit, rotation / settings.orientation_tolerance)
        return np.asarray(merit, dtype=float)

    def objective(self, errors: FloatArray, weights: FloatArray) -> float:
        r"""Weighted least squares :math:`\tfrac12\sum_{k\ge1} \omega_k \|S e_k\|^2`."""
        scaled = errors[1:] * self.scale
        value = 0.5 * float(np.sum(weights * np.sum(scaled * scaled, axis=1)))
        return value if math.isfinite(value) else math.inf

    def linearise(self, path: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        r"""Gradient and Hessian blocks of ``½‖S e_k‖²`` at samples ``1..N−1``.

        .. math:: g_k = -\tilde J_k^\top \tilde e_k, \qquad
                  H_k = \tilde J_k^\top \tilde J_k
                        - \sum_j \Big(\frac{\partial J_k}{\partial q_j}\Big)^{\!\top}
                          S^2 e_k\; \mathbf e_j^\top

        (``J̃ = S J``); the second, curvature term is what makes the solve converge at the
        workspace boundary, where ``J̃ᵀJ̃`` loses rank. It is proportional to the residual and
        left out where ``‖S e_k‖ ≤`` :data:`CURVATURE_RESIDUAL`. It uses
        ``Robot.jacobian_derivative`` (exact for Pinocchio arms; for the pose error it ignores
        the derivative of ``log₃``, so it is Gauss–Newton-accurate there).

        Returns:
            ``(errors (N, n), gradients (N−1, nv), hessians (N−1, nv, nv))``; the
            Hessians are symmetrised but not yet made positive definite.
        """
        robot, nv = self.robot, self.nv
        count = self.samples
        errors = np.zeros((count, robot.task_dim))
        square = self.scale * self.scale
        errors[0] = self.kinematics.errors(path[:1])[0]
        errors[1:], jacobians = self.kinematics.errors_and_jacobians(path[1:], first=1)
        scaled = self.scale[None, :, None] * jacobians  # (N−1, n, nv)
        transposed = scaled.transpose(0, 2, 1)
        residuals = self.scale * errors[1:]
        gradients = -(transposed @ residuals[:, :, None])[:, :, 0]
        blocks = transposed @ scaled  # Gauss–Newton part, (N−1, nv, nv)
        for k in range(1, count):
            if float(np.linalg.norm(residuals[k - 1])) > CURVATURE_RESIDUAL:
                pull = square * errors[k]
                derivatives = self.kinematics.jacobian_derivatives(path[k])
                blocks[k - 1] = blocks[k - 1] - np.column_stack(
                    [derivatives[j].T @ pull for j in range(nv)]
                )
        hessians = 0.5 * (blocks + blocks.transpose(0, 2, 1))
        return errors, gradients, hessians
