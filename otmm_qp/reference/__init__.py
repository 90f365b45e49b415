"""Offline-optimal reference: the best joint path within the limits for a whole task."""

from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.reference.result import LABELS, REFERENCE_COLUMNS, Bracket, ReferenceResult, as_run
from otmm_qp.reference.settings import LIMIT_TOUCH, ReferenceSettings
from otmm_qp.reference.solve import Candidate, solve_reference

__all__ = [
    "LABELS",
    "Bracket",
    "Candidate",
    "LIMIT_TOUCH",
    "REFERENCE_COLUMNS",
    "ReferenceResult",
    "ReferenceSettings",
    "TrackingProblem",
    "as_run",
    "solve_reference",
]
