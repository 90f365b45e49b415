r"""Task errors and Jacobians of many samples of one task: one lean Pinocchio pass per sample.

For the samples ``k`` of a path ``Q`` (shape ``(M, nv)``, joint coordinates) and their targets
``x_d(t_k)``:

.. math::
    e_k = e(x_d(t_k), f(q_k)) \quad (M, n), \qquad J_k = \partial f/\partial q\,(q_k)
    \quad (M, n, nv),

the same numbers, in the same floating-point operations, as
``robot.task_error(x_d(t_k), robot.forward(robot.configuration(q_k)))`` and
``robot.kinematics(...)`` one sample at a time. On a Pinocchio arm with Euclidean
coordinates (no continuous joint) the per-sample Python work is cut to the Pinocchio calls
themselves: no Jacobian where only the error is asked for (``Robot.forward`` computes one), no
configuration copies, the position differences and the relative rotations
``R^* R^\top`` [-] of every sample in one NumPy operation each, then ``log₃`` per sample.
Any other robot takes the per-sample calls (the definition). The reference's inner loops
(:meth:`~otmm_qp.reference.problem.TrackingProblem.errors`, its linearisation and the cone
program's) evaluate every trial path here.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from otmm_qp.exceptions import DimensionError
from otmm_qp.robots.robot import FloatArray, Robot


class SampleKinematics:
    """Errors and Jacobians of a task's samples (module docstring).

    Args:
        robot: The arm.
        targets: ``x_d(t_k)`` of every sample ``k = 0..N−1`` (the task's values: ``(3,)``
            positions [m] or ``(4, 4)`` poses).
    """

    def __init__(self, robot: Robot, targets: Sequence[FloatArray]) -> None:
        from otmm_qp.robots.pinocchio_arm import PinocchioArm

        self.robot = robot
        self.targets = targets
        self.lean = isinstance(robot, PinocchioArm) and robot.nq == robot.nv
        self.pose = robot.task_dim == 6
        # its own workspace: the robot's ``data`` (the controllers') is left as it was
        self._data = robot.model.createData() if self.lean else None  # type: ignore[attr-defined]
        stacked = np.array([np.asarray(t, dtype=float) for t in targets])
        if self.lean and self.pose:
            self._positions = np.ascontiguousarray(stacked[:, :3, 3])  # (N, 3) [m]
            self._rotations = np.ascontiguousarray(stacked[:, :3, :3])  # (N, 3, 3)
        elif self.lean:
            self._positions = stacked.reshape(len(targets), -1)  # (N, 3) [m]

    def errors(self, path: FloatArray, first: int = 0) -> FloatArray:
        """Task errors of samples ``first .. first + M − 1`` at ``path`` ``(M, nv)``, ``(M, n)``.

        Raises:
            DimensionError: ``path`` is not ``(M, nv)`` with ``first + M ≤ N``.
        """
        self._check(path, first)
        if not self.lean:
            robot = self.robot
            return np.array(
                [
                    robot.task_error(self.targets[first + k], robot.forward(robot.configuration(q)))
                    for k, q in enumerate(path)
                ]
            )
        model, data, frame = self._pinocchio()
        count = path.shape[0]
        translations = np.empty((count, 3))
        rotations = np.empty((count, 3, 3)) if self.pose else None
        for k in range(count):
            pin.forwardKinematics(model, data, path[k])
            placement = pin.updateFramePlacement(model, data, frame)
            _store(placement, k, translations, rotations)
        return self._finish(translations, rotations, first)

    def errors_and_jacobians(
        self, path: FloatArray, first: int = 0
    ) -> tuple[FloatArray, FloatArray]:
        """Errors ``(M, n)`` and Jacobians ``(M, n, nv)`` of samples ``first ..`` at ``path``.

        Raises:
            DimensionError: ``path`` is not ``(M, nv)`` with ``first + M ≤ N``.
        """
        self._check(path, first)
        robot = self.robot
        count = path.shape[0]
        jacobians = np.empty((count, robot.task_dim, robot.nv))
        if not self.lean:
            errors = np.empty((count, robot.task_dim))
            for k, q in enumerate(path):
                x, jacobians[k] = robot.kinematics(robot.configuration(q))
                errors[k] = robot.task_error(self.targets[first + k], x)
            return errors, jacobians
        model, data, frame = self._pinocchio()
        rows = robot.task_dim
        world = pin.LOCAL_WORLD_ALIGNED
        translations = np.empty((count, 3))
        rotations = np.empty((count, 3, 3)) if self.pose else None
        for k in range(count):
            q = path[k]
            pin.forwardKinematics(model, data, q)
            placement = pin.updateFramePlacement(model, data, frame)
            jacobians[k] = pin.computeFrameJacobian(model, data, q, frame, world)[:rows]
            _store(placement, k, translations, rotations)
        return self._finish(translations, rotations, first), jacobians

    def sample(self, q: FloatArray, index: int) -> tuple[FloatArray, FloatArray]:
        """Error ``(n,)`` and Jacobian ``(n, nv)`` of sample ``index`` at coordinates ``q``."""
        robot = self.robot
        if not self.lean:
            x, jacobian = robot.kinematics(robot.configuration(q))
            return robot.task_error(self.targets[index], x), jacobian
        model, data, frame = self._pinocchio()
        pin.forwardKinematics(model, data, q)
        placement = pin.updateFramePlacement(model, data, frame)
        jacobian = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)
        if not self.pose:
            return self._positions[index] - placement.translation, jacobian[:3].copy()
        homogeneous = placement.homogeneous
        error = np.empty(6)
        error[:3] = self._positions[index] - homogeneous[:3, 3]
        error[3:] = pin.log3(self._rotations[index] @ homogeneous[:3, :3].T)
        return error, jacobian

    def jacobian_derivatives(self, q: FloatArray) -> FloatArray:
        r"""``∂J/∂q_j`` at joint coordinates ``q`` for every ``j``, shape ``(nv, n, nv)``.

        ``Robot.jacobian_derivative`` along each unit direction ``e_j`` (on a Pinocchio arm:
        ``computeJointJacobiansTimeVariation`` then ``getFrameJacobianTimeVariation``,
        ``LOCAL_WORLD_ALIGNED``; the frame placements of the other frames are not updated).
        """
        robot = self.robot
        nv = robot.nv
        unit = np.eye(nv)
        out = np.empty((nv, robot.task_dim, nv))
        if not self.lean:
            configuration = robot.configuration(q)
            for j in range(nv):
                out[j] = robot.jacobian_derivative(configuration, unit[j])
            return out
        model, data, frame = self._pinocchio()
        rows = robot.task_dim
        world = pin.LOCAL_WORLD_ALIGNED
        for j in range(nv):
            # (the frame's placement is recomputed by getFrameJacobianTimeVariation itself)
            pin.computeJointJacobiansTimeVariation(model, data, q, unit[j])
            out[j] = pin.getFrameJacobianTimeVariation(model, data, frame, world)[:rows]
        return out

    def _check(self, path: FloatArray, first: int) -> None:
        room = len(self.targets) - first
        shape = np.shape(path)
        if len(shape) != 2 or shape[1] != self.robot.nv or not 0 <= shape[0] <= room:
            raise DimensionError("path", (room, self.robot.nv), shape)

    def _pinocchio(self) -> tuple[object, object, int]:
        robot = self.robot
        return robot.model, self._data, robot.frame_id  # type: ignore[attr-defined]

    def _finish(
        self, translations: FloatArray, rotations: FloatArray | None, first: int
    ) -> FloatArray:
        """``(p* − p, log₃(R* Rᵀ))`` per sample (position task: ``p* − p``)."""
        count = translations.shape[0]
        window = slice(first, first + count)
        position = self._positions[window] - translations
        if rotations is None:
            return np.asarray(position, dtype=float)
        relative = self._rotations[window] @ rotations.transpose(0, 2, 1)
        errors = np.empty((count, 6))
        errors[:, :3] = position
        for k in range(count):
            errors[k, 3:] = pin.log3(relative[k])
        return errors


def _store(
    placement: pin.SE3, k: int, translations: FloatArray, rotations: FloatArray | None
) -> None:
    """Write a frame placement into row ``k`` of ``translations`` (and ``rotations``)."""
    if rotations is None:
        translations[k] = placement.translation
    else:
        homogeneous = placement.homogeneous
        translations[k] = homogeneous[:3, 3]
        rotations[k] = homogeneous[:3, :3]
