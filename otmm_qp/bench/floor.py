r"""The floor of one control step: the arm's kinematics, its Jacobian and one LAPACK SVD.

.. math:: q \;\mapsto\; x(q),\ J(q) \;\mapsto\; U\Sigma V^\top = J

nothing else: no checks, no task weight, no filter, no backend. For a Pinocchio arm it is
Pinocchio's own calls (``forwardKinematics``, ``updateFramePlacement``,
``computeFrameJacobian``) and ``dgesdd`` (``scipy.linalg.lapack``, thin, ``overwrite_a``, the
``lwork`` of :class:`~otmm_qp.state.SvdWorkspace`) on the Jacobian Pinocchio returns; for any
other robot (the planar arm) its :meth:`~otmm_qp.robots.Robot.kinematics` and the same
``dgesdd``. Every pipeline needs at least this much per step, so its ratio to the floor is the
cost of everything otmm-qp (or a peer) adds around it.
"""

from __future__ import annotations

from collections.abc import Callable

import pinocchio as pin
from scipy.linalg import lapack

from otmm_qp.bench.scenarios import Scenario
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.robots.robot import FloatArray
from otmm_qp.state import SvdWorkspace

#: Row label of the floor in the bench tables.
FLOOR = "floor (FK + Jacobian + dgesdd)"


def floor_step(scenario: Scenario) -> tuple[str, Callable[[int], None]]:
    """The floor's step function on ``scenario``'s states, and what it calls (one line)."""
    robot, configurations = scenario.robot, scenario.q
    rows, nv = robot.task_dim, robot.nv
    lwork = SvdWorkspace((rows, nv)).lwork  # the length KinematicState's SVD uses
    dgesdd = lapack.dgesdd
    if isinstance(robot, PinocchioArm):
        model, data, frame = robot.model, robot.data, robot.frame_id
        forward, place = pin.forwardKinematics, pin.updateFramePlacement
        jacobian, axes = pin.computeFrameJacobian, pin.LOCAL_WORLD_ALIGNED

        def pinocchio_run(k: int) -> None:
            q = configurations[k]
            forward(model, data, q)
            place(model, data, frame)
            matrix: FloatArray = jacobian(model, data, q, frame, axes)
            dgesdd(matrix if rows == 6 else matrix[:rows], 1, 0, lwork, 1)

        calls = "Pinocchio forwardKinematics + updateFramePlacement + computeFrameJacobian + dgesdd"
        return calls, pinocchio_run
    kinematics = robot.kinematics

    def run(k: int) -> None:
        dgesdd(kinematics(configurations[k])[1], 1, 0, lwork, 1)

    return f"{type(robot).__name__}.kinematics + dgesdd", run
