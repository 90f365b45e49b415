"""A stored certificate ``kind@k`` recomputed from its stated definition.

``reference.certificate`` names the bound and the sample that set a task's lower bound
(:attr:`~otmm_qp.reference.bound.LowerBound.certificate`); :func:`recompute` evaluates that
bound again on the task's problem, with the budgets the reference uses (counts, so the value
reproduces to the last bit on any machine).
"""

from __future__ import annotations

from otmm_qp.exceptions import ParameterError
from otmm_qp.reference.bound import lower_bound
from otmm_qp.reference.coupled_bound import CoupledSearch
from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.reference.sample_bound import SampleSearch
from otmm_qp.reference.solve import SEARCH_BOXES

#: Kinds :func:`~otmm_qp.reference.bound.lower_bound` itself gives.
CLOSED_FORM = ("start", "reach", "travel", "turn", "wrist")


def recompute(problem: TrackingProblem, certificate: str) -> float:
    """The lower bound [tolerances] the certificate ``kind@k`` states (0 for ``none``).

    Raises:
        ParameterError: An unknown kind, a malformed certificate or a sample out of range;
            or a closed-form kind that is not the kind of its sample.
    """
    if certificate == "none":
        return 0.0
    kind, _, text = certificate.partition("@")
    if not text.isdigit() or not 0 <= int(text) < problem.samples:
        raise ParameterError("reference.certificate", f"expected kind@sample, got {certificate!r}")
    sample = int(text)
    if kind == "search":
        return SampleSearch(problem).bound(sample, SEARCH_BOXES).merit
    if kind == "coupled":
        outcome = CoupledSearch(problem).run(last=sample)
        return outcome.merit if outcome.sample == sample else 0.0
    if kind in CLOSED_FORM:
        bound = lower_bound(problem)
        if bound.kinds[sample] != kind:
            raise ParameterError(
                "reference.certificate", f"sample {sample} is {bound.kinds[sample]!r}"
            )
        return float(bound.merit[sample])
    raise ParameterError(
        "reference.certificate", f"unknown kind {kind!r}; allowed: search, coupled, {CLOSED_FORM}"
    )
