r"""The secondary-task interface: a desired joint velocity for the redundancy left by the task."""

from __future__ import annotations

import abc
import math

from otmm_qp.exceptions import ParameterError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState


def finite_number(field: str, value: object, low: float = 0.0, strict: bool = False) -> float:
    """``value`` as a float, or a :class:`ParameterError` naming ``field``.

    Accepted: a finite number ``> low`` (``strict``) or ``>= low``; booleans are refused.
    """
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ParameterError(field, f"must be a finite number, got {value!r:.40}")
    if not (value > low if strict else value >= low):
        raise ParameterError(field, f"must be {'>' if strict else '>='} {low:g}, got {value!r:.40}")
    return float(value)


class SecondaryTask(abc.ABC):
    r"""A joint-space secondary task :math:`\dot q_2(q)` [rad/s], shape ``(nv,)``.

    Backends with redundancy (task priority, J-PARSE's null-space term) project it into what
    the primary task leaves free. Being joint-space tasks (:math:`J_2 = I`), their own
    inverse is the identity, so Chiaverini's :math:`J_2^{\#}\dot x_2` is :math:`\dot q_2`.
    """

    #: Name used in YAML (``secondary: {type: NAME, ...}``).
    name: str = "secondary"

    def bind(self, robot: Robot) -> None:  # noqa: B027 - optional hook
        """Check parameters against the robot (dimensions); called once per run."""

    @abc.abstractmethod
    def joint_velocity(self, robot: Robot, state: KinematicState) -> FloatArray:
        """Desired joint velocity [rad/s], shape ``(nv,)``, finite, at ``state``."""
