r"""The streaming interface's thresholds on the command stream: checked, never applied.

An arm's real-time interface may refuse a command stream instead of smoothing it: the Franka
FCI aborts the motion (a "reflex", ``franka::CommandException``) when the commanded joint
acceleration or jerk passes its limits, and libfranka's ``limit_rate``, which would clip the
stream first, is **off** by default (``include/franka/robot.h``: ``bool limit_rate = false``).
This stage passes every command through unchanged and declares the thresholds
(:mod:`otmm_qp.plants.declaration`):

.. math::
    |\dot q_k - \dot q_{k-1}|/dt \le a,\qquad
    |\dot q_k - 2\dot q_{k-1} + \dot q_{k-2}|/(dt\,p) \le j

per joint (:math:`\dot q_{-1} = \dot q_{-2} = 0`: from rest), [rad/s²] and [rad/s³], with
:math:`p = \min(dt, \text{period})` the interface's own period. A controller slower than the
interface (the studies' 50 Hz against the FCI's 1 kHz) is taken to interpolate its velocity
linearly over each control period — the acceleration the interface sees is then constant over
the period, :math:`\Delta\dot q/dt`, and changes at a period's boundary within one interface
period, a jerk :math:`\Delta^2\dot q/(dt\,p)`. (Holding the command instead would show the
interface :math:`\Delta\dot q/p`: no controller at 50 Hz could stay within 7.5 rad/s².) The run's
metrics count the steps that pass them (``command_acceleration_violations``,
``command_jerk_violations``, :mod:`otmm_qp.metrics.metrics`), a study's failure cause
``interface_abort`` says the interface would have aborted; a controller's ``command`` limit
(:mod:`otmm_qp.limits.command_limit`) reads the thresholds to keep the stream within them.
"""

from __future__ import annotations

from collections.abc import Sequence
from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.plants.declaration import PlantDeclaration
from otmm_qp.plants.plant import Plant
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.validation import (
    Constraints,
    Interval,
    check_params,
    per_joint,
    positive_per_joint,
)

__all__ = ["InterfaceLimits"]


class InterfaceLimits(Plant):
    r"""The interface's acceleration and jerk thresholds (see the module); a pass-through.

    Args:
        acceleration: :math:`a` > 0 [rad/s²] (inf: that joint unchecked), a scalar or one per
            joint.
        jerk: :math:`j` > 0 [rad/s³] likewise, or None: not checked.
        period: The interface's period p > 0 [s] (the FCI's 1 ms), or None: the control period.

    Raises:
        ParameterError: A value that is not > 0, or NaN (naming it).
    """

    name: ClassVar[str] = "interface"
    parameter_constraints: ClassVar[Constraints] = {
        "acceleration": positive_per_joint("rad/s²"),
        "jerk": [positive_per_joint("rad/s³"), None],
        "period": [Interval(Real, 0, None, closed="neither", unit="s"), None],
    }

    def __init__(
        self,
        acceleration: float | Sequence[float],
        jerk: float | Sequence[float] | None = None,
        period: float | None = None,
    ) -> None:
        check_params(self, locals())
        self.acceleration = acceleration
        self.jerk = jerk
        self.period = None if period is None else float(period)

    def reset(self, robot: Robot, q0: FloatArray, dt: float) -> None:
        """Check the lengths against the robot.

        Raises:
            DimensionError: A value is neither a scalar nor one per joint.
        """
        per_joint(self.acceleration, "acceleration", robot.nv)
        per_joint(self.jerk, "jerk", robot.nv)

    def declares(self, dt: float) -> PlantDeclaration:
        """The thresholds (one value, or one per joint)."""
        jerk = () if self.jerk is None else _values(self.jerk)
        return PlantDeclaration(
            interface_acceleration=_values(self.acceleration),
            interface_jerk=jerk,
            interface_period=self.period or 0.0,
        )

    def label(self) -> str:
        """``interface(a=…, j=…)`` (per-joint values joined by ``/``)."""
        parts = [f"a={'/'.join(f'{x:g}' for x in _values(self.acceleration))}"]
        if self.jerk is not None:
            parts.append(f"j={'/'.join(f'{x:g}' for x in _values(self.jerk))}")
        if self.period is not None:
            parts.append(f"p={self.period:g}")
        return f"interface({', '.join(parts)})"


def _values(value: float | Sequence[float]) -> tuple[float, ...]:
    return tuple(float(x) for x in np.atleast_1d(np.asarray(value, dtype=float)))
