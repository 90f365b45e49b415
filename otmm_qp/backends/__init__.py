"""Backend interface; the built-in backends live in ``controllers/`` (``otmm_qp_controllers``)."""

from otmm_qp.backends.backend import (
    RCOND,
    STATUS_BOUNDED,
    STATUS_INFEASIBLE,
    STATUS_NONFINITE,
    STATUS_OK,
    STATUS_RELAXED,
    STATUS_SATURATED,
    STATUS_STUCK,
    STATUSES,
    Backend,
    BackendOutput,
    rank_cutoff,
    truncated_pseudoinverse_apply,
)
from otmm_qp.status import Status

__all__ = [
    "RCOND",
    "STATUSES",
    "STATUS_BOUNDED",
    "STATUS_INFEASIBLE",
    "STATUS_NONFINITE",
    "STATUS_OK",
    "STATUS_RELAXED",
    "STATUS_SATURATED",
    "STATUS_STUCK",
    "Backend",
    "BackendOutput",
    "Status",
    "rank_cutoff",
    "truncated_pseudoinverse_apply",
]
