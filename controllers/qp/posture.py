r"""The QP's posture cost as one value: weight, gain and nominal posture together."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from numbers import Real
from typing import Any, ClassVar

import numpy as np

from otmm_qp.exceptions import ParameterError
from otmm_qp.robots.robot import FloatArray
from otmm_qp.validation import ArrayOf, Constraints, Interval, check_params

__all__ = ["POSTURE_MOVED", "QpPosture"]


@dataclass(frozen=True)
class QpPosture:
    r"""The posture term of the QP cost.

    .. math:: \tfrac12 w_p\,\|\dot q - g_p(\theta_{nom} - \theta)\|^2

    YAML: ``posture: {weight: w_p, gain: g_p, q_nominal: [...]}`` (formerly the three keys
    ``posture_weight``, ``posture_gain``, ``q_nominal`` of ``qp``). Checks itself once, when
    made; the length of ``q_nominal`` against the robot is checked when the backend is bound.

    Attributes:
        weight: ``w_p ≥ 0`` (0: no posture cost).
        gain: ``g_p ≥ 0`` [1/s] of the posture velocity.
        q_nominal: ``θ_nom`` joint coordinates [rad or m], shape ``(nv,)``; None: the first
            state seen after the backend's ``reset``.
    """

    parameter_constraints: ClassVar[Constraints] = {
        "weight": Interval(Real, 0, None, closed="left"),
        "gain": Interval(Real, 0, None, closed="left", unit="1/s"),
        "q_nominal": [ArrayOf(Interval(Real, None, None), per="joint"), None],
    }

    weight: float = 0.0
    gain: float = 1.0
    q_nominal: FloatArray | None = None

    def __post_init__(self) -> None:
        """Check the fields against :attr:`parameter_constraints`; store floats."""
        check_params(self, {"weight": self.weight, "gain": self.gain, "q_nominal": self.q_nominal})
        object.__setattr__(self, "weight", float(self.weight))
        object.__setattr__(self, "gain", float(self.gain))
        if self.q_nominal is not None:
            object.__setattr__(self, "q_nominal", np.asarray(self.q_nominal, dtype=float))

    @classmethod
    def from_spec(cls, spec: QpPosture | Mapping[str, Any] | None) -> QpPosture:
        """The posture of a ``posture:`` option (a mapping, a :class:`QpPosture` or None: none).

        Raises:
            ParameterError: An unknown key or a refused value, as ``posture.<key>``.
        """
        if spec is None:
            return cls()
        if isinstance(spec, QpPosture):
            return spec
        allowed = list(cls.parameter_constraints)
        for key in spec:
            if key not in allowed:
                raise ParameterError(
                    f"posture.{key}", f"unknown parameter; allowed: {', '.join(allowed)}"
                )
        try:
            return cls(**spec)
        except ParameterError as error:
            raise ParameterError(f"posture.{error.field}", error.message) from None


#: The older ``qp`` keys the posture replaces, refused with what to write instead.
POSTURE_MOVED: dict[str, str] = {
    key: (
        "moved into posture: {weight: W, gain: G, q_nominal: [...]} "
        f"(write posture: {{{new}: ...}})"
    )
    for key, new in (
        ("posture_weight", "weight"),
        ("posture_gain", "gain"),
        ("q_nominal", "q_nominal"),
    )
}
