"""Backend interface; the built-in backends live in ``controllers/`` (``otmm_qp_controllers``)."""

from otmm_qp.backends.backend import (
    STATUS_BOUNDED,
    STATUS_INFEASIBLE,
    STATUS_NONFINITE,
    STATUS_OK,
    STATUS_STUCK,
    STATUSES,
    Backend,
    BackendOutput,
    truncated_pseudoinverse_apply,
)

__all__ = [
    "STATUSES",
    "STATUS_BOUNDED",
    "STATUS_INFEASIBLE",
    "STATUS_NONFINITE",
    "STATUS_OK",
    "STATUS_STUCK",
    "Backend",
    "BackendOutput",
    "truncated_pseudoinverse_apply",
]
