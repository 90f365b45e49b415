r"""Receding-horizon preview IK: one QP per control step over a horizon of the known future.

One concept, one idea per file:

* :mod:`.knots` — :class:`KnotGrid`, the horizon's knots (fine steps at ``dt``, then coarse
  ones: move blocking) and the shift of a plan into the next step's nominal;
* :mod:`.formulation` — :class:`PreviewProblem`, the QP (task error at every knot linearised
  along the nominal, smoothness on second differences, hard limits) written in place;
* :mod:`.parameters` — :class:`PreviewParameters`, every parameter in one frozen, checked
  object, and the rule of the peak weights (``peak_scale``);
* :mod:`.targets` — what each knot misses: the desired path (preview) or the held command
  (causal);
* :mod:`.backend` — :class:`PreviewBackend` (entry point ``preview``) and
  :class:`CausalPreviewBackend` (``preview_causal``);
* :mod:`.two_rate` — :class:`TwoRatePreviewBackend` (``preview_two_rate``): the preview QP
  every ``N`` steps, the one-step ``qp`` backend tracking its plan in between.
"""

from .backend import CausalPreviewBackend, PreviewBackend, PreviewStep
from .formulation import PreviewProblem, PreviewWeights
from .knots import KnotGrid
from .parameters import PreviewParameters
from .targets import HeldCommandTargets, Targets, TrajectoryTargets
from .two_rate import TwoRatePreviewBackend

__all__ = [
    "CausalPreviewBackend",
    "HeldCommandTargets",
    "KnotGrid",
    "PreviewBackend",
    "PreviewParameters",
    "PreviewProblem",
    "PreviewStep",
    "PreviewWeights",
    "Targets",
    "TrajectoryTargets",
    "TwoRatePreviewBackend",
]
