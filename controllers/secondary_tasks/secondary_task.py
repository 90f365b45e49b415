r"""The secondary-task interface: a desired joint velocity for the redundancy left by the task."""

from __future__ import annotations

import abc

from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState


class SecondaryTask(abc.ABC):
    r"""A joint-space secondary task :math:`\dot q_2(q)` [rad/s], shape ``(nv,)``.

    Backends with redundancy (task priority, J-PARSE's null-space term) project it into what
    the primary task leaves free. Being joint-space tasks (:math:`J_2 = I`), their own
    inverse is the identity, so Chiaverini's :math:`J_2^{\#}\dot x_2` is :math:`\dot q_2`.

    A task declares ``parameter_constraints`` (:mod:`otmm_qp.validation`) and checks them in
    ``__init__``; :func:`~otmm_qp_controllers.secondary_tasks.secondary_task_from` prefixes a
    refused field with ``secondary.``.
    """

    #: Name used in YAML (``secondary: {type: NAME, ...}``).
    name: str = "secondary"

    def bind(self, robot: Robot) -> None:  # noqa: B027 - optional hook
        """Check parameters against the robot (dimensions); called once per run."""

    @abc.abstractmethod
    def joint_velocity(self, robot: Robot, state: KinematicState) -> FloatArray:
        """Desired joint velocity [rad/s], shape ``(nv,)``, finite, at ``state``."""
