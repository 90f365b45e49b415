"""Backend interface; the built-in backends live in ``controllers/`` (``otmm_qp_controllers``)."""

from otmm_qp.backends.backend import (
    RCOND,
    Backend,
    BackendOutput,
    rank_cutoff,
    svd_work,
    truncated_pseudoinverse_apply,
)
from otmm_qp.status import Status

__all__ = [
    "RCOND",
    "Backend",
    "BackendOutput",
    "Status",
    "rank_cutoff",
    "svd_work",
    "truncated_pseudoinverse_apply",
]
