"""Joint limits as objects: each returns a velocity box (or a constraint row) per step.

One concept per file: the interfaces (:mod:`~otmm_qp.limits.limit`), one class per limit
(``velocity_limit``, ``position_limit``, ``predicted_position_limit`` with its
:mod:`~otmm_qp.limits.command_prediction`, ``acceleration_limit``, ``command_limit``
(soft: given up braking first), ``fr3_velocity``, ``singularity_barrier``),
their composition (:mod:`~otmm_qp.limits.box`: intersection, priority relaxation, conflict)
and the one YAML form with the mapping of older keys (:mod:`~otmm_qp.limits.options`). New
limits register in the entry-point group ``otmm_qp.limits`` like any plugin.
"""

from otmm_qp.limits.acceleration_limit import AccelerationLimit
from otmm_qp.limits.box import LimitBox, conflict, intersect, relaxed, soften
from otmm_qp.limits.command_limit import CommandLimit
from otmm_qp.limits.fr3_velocity_limit import Fr3VelocityLimit
from otmm_qp.limits.limit import BaseLimit, Box, Limit, Row, RowLimit, per_joint
from otmm_qp.limits.options import LimitSet, LimitSpec, make_limits
from otmm_qp.limits.position_limit import PositionLimit
from otmm_qp.limits.predicted_position_limit import PredictedPositionLimit
from otmm_qp.limits.singularity_barrier import SingularityBarrier
from otmm_qp.limits.velocity_limit import VelocityLimit

__all__ = [
    "AccelerationLimit",
    "BaseLimit",
    "Box",
    "CommandLimit",
    "Fr3VelocityLimit",
    "Limit",
    "LimitBox",
    "LimitSet",
    "LimitSpec",
    "PositionLimit",
    "PredictedPositionLimit",
    "Row",
    "RowLimit",
    "SingularityBarrier",
    "VelocityLimit",
    "conflict",
    "intersect",
    "make_limits",
    "per_joint",
    "relaxed",
    "soften",
]
