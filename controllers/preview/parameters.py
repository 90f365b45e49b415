r"""The preview backends' parameters as one frozen, checked object.

:class:`PreviewParameters` holds what a config gives a ``preview``/``preview_causal`` backend
(and, less ``working_set``, the preview part of ``preview_two_rate``): built from the
constructor's keywords (:meth:`PreviewParameters.pick`), checked once against
:data:`PREVIEW_CONSTRAINTS` (the plugins' declarations, so ``otmm-qp list`` and a config's
errors are unchanged), and handed on whole — no constructor re-lists and forwards them by
position (:meth:`PreviewParameters.keywords`).

The peak weights' rule (``peak_scale``):

* ``absolute`` (default): ``peak`` = ω and ``peak_jump`` = ω_a are the QP's weights
  [task units² / (rad/s)] as given;
* ``arm``: they are dimensionless, ω̂ and ω̂_a, and the QP's weights come from the arm and the
  task each step,

  .. math:: \omega = \hat\omega\,\frac{\bar v^2}{\dot q_{lim}},\qquad
            \omega_a = \hat\omega_a\,\frac{\bar v^2}{\dot q_{lim}},\qquad
            \bar v = \max_{t' \le t}\frac{\|W\,e(x_d(t' + H),\ x_d(t'))\|}{H}

  with :math:`\dot q_{lim}` [rad/s] the smallest of the arm's joint speed limits (its model's,
  capped by a ``velocity`` limit's ``max_speed``; 1 rad/s when none is finite) and
  :math:`\bar v` [weighted task units/s] the fastest chord speed of the preview window seen so
  far in the episode (the causal backend: of the held command, :math:`\|\dot x_w\|`). Reading:
  reaching the arm's speed limit costs ω̂ times the task term of lagging the episode's fastest
  motion by one step (the task term is in units of one step's velocity, :mod:`.formulation`),
  so the weights follow the task's speed (a motion 1.4× faster weighs its peaks 1.96× more)
  and the arm's limits, and one ω̂ serves both arms and both speeds. The running maximum, like
  the epigraphs' floors, never lowers a weight when the path slows down (a weight that fell to
  0 at the end of a motion would let the last steps jump).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from numbers import Integral, Real
from typing import Any, Literal

from otmm_qp.limits import LimitSpec
from otmm_qp.limits.options import LIMITS
from otmm_qp.validation import Boolean, Constraints, Interval, OneOf, check_params

from ..qp.box_backend import SOLVER
from .knots import BYTES_PER_ENTRY, MAX_KNOTS, MAX_QP_BYTES

__all__ = ["PEAK_SCALES", "POLICIES", "PREVIEW_CONSTRAINTS", "PreviewParameters"]

InfeasiblePolicy = Literal["raise", "hold", "dls"]
PeakScale = Literal["absolute", "arm"]
#: The infeasibility policies of the preview backends.
POLICIES = ("raise", "hold", "dls")
#: The rules of the peak weights (module docstring).
PEAK_SCALES = ("absolute", "arm")

_WEIGHT = Interval(Real, 0, None, closed="left")
#: What bounds ``knots`` and ``fine_steps`` (the QP's memory grows as their square).
_KNOTS = (
    f"segments; the QP's dense matrices take ~{BYTES_PER_ENTRY}·(K·n)² bytes on n joints, at "
    f"most {MAX_QP_BYTES // 2**20} MiB"
)

#: The declarations of every preview parameter (the plugins' ``parameter_constraints``).
PREVIEW_CONSTRAINTS: Constraints = {
    "horizon": Interval(Real, 0, None, closed="neither", unit="s"),
    "knots": Interval(Integral, 1, MAX_KNOTS, unit=_KNOTS),
    "fine_steps": Interval(Integral, 1, MAX_KNOTS, unit=_KNOTS),
    "coarse_step": [Interval(Real, 0, None, closed="neither", unit="s"), None],
    "regularization": Interval(Real, 0, None, closed="neither"),
    "smoothness": _WEIGHT,
    "jump": _WEIGHT,
    "trust_region": _WEIGHT,
    "peak": _WEIGHT,
    "peak_jump": _WEIGHT,
    "peak_scale": OneOf(*PEAK_SCALES),
    "solver": SOLVER,
    "limits": [LIMITS, None],
    "infeasible_policy": OneOf(*POLICIES),
    "fast_path": Boolean(),
    "working_set": Boolean(),
}


@dataclass(frozen=True, kw_only=True)
class PreviewParameters:
    """Every parameter of a preview backend, checked at construction (see the backends).

    Attributes:
        horizon: ``H`` [s], > 0.
        knots: Cap ``K`` on the horizon's segments, an integer ≥ 1.
        fine_steps: Segments of one ``dt`` at the start, an integer ≥ 1.
        coarse_step: Length Δ [s] of the later segments, or None.
        regularization: μ > 0.
        smoothness: ρ ≥ 0.
        jump: ρ₀ ≥ 0.
        trust_region: κ ≥ 0.
        peak: ω ≥ 0 (``absolute``) or ω̂ ≥ 0 (``arm``).
        peak_jump: ω_a ≥ 0 (``absolute``) or ω̂_a ≥ 0 (``arm``).
        peak_scale: ``absolute`` or ``arm`` (module docstring).
        solver: The QP solver's name.
        limits: The project's limits, or None (velocity and position).
        infeasible_policy: ``raise``, ``hold`` or ``dls``.
        fast_path: Skip the solver when the last active set gives the optimum.
        working_set: Solve on the working rows only.

    Raises:
        ParameterError: A value out of range, naming the field and what is allowed.
    """

    parameter_constraints = PREVIEW_CONSTRAINTS  # not a field: no annotation

    horizon: float = 1.0
    knots: int = 16
    fine_steps: int = 4
    coarse_step: float | None = None
    regularization: float = 1e-4
    smoothness: float = 0.001
    jump: float = 0.0
    trust_region: float = 1e-3
    peak: float = 0.0
    peak_jump: float = 0.0
    peak_scale: PeakScale = "absolute"
    solver: str = "daqp"
    limits: Sequence[LimitSpec] | None = None
    infeasible_policy: InfeasiblePolicy = "raise"
    fast_path: bool = True
    working_set: bool = False

    def __post_init__(self) -> None:
        """Check every value against :data:`PREVIEW_CONSTRAINTS`."""
        check_params(self, self.keywords())

    @classmethod
    def pick(cls, values: Mapping[str, Any]) -> PreviewParameters:
        """The parameters among ``values`` (e.g. a constructor's ``locals()``), the rest default."""
        return cls(**{f.name: values[f.name] for f in fields(cls) if f.name in values})

    def keywords(self) -> dict[str, Any]:
        """Every parameter by name (a constructor's keywords)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}
