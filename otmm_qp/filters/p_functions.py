r"""Scalar adjusting functions :math:`p(\sigma_{min})` of OTMM (paper eq. 8).

Each maps ``s = σ_min ∈ [0, σ_S]`` to ``p ∈ [0, 1]``, monotone decreasing with
``p(0) = 1`` and ``p(σ_S) = 0``. With ``ratio = clip(s/σ_S, 0, 1)``:

* ``linear``: :math:`p = 1 - s/\sigma_S`
* ``sqrt``:   :math:`p = 1 - \sqrt{s/\sigma_S}`
* ``cbrt``:   :math:`p = 1 - \sqrt[3]{s/\sigma_S}`
* ``power``:  :math:`p = 1 - (s/\sigma_S)^a`, ``a > 0``

Along the singular direction the joint speed per unit command is
:math:`(1-p)/\sigma = (s/\sigma_S)^a/s`, bounded by :math:`1/\sigma_S` only for ``a ≥ 1``;
for ``a < 1`` (sqrt, cbrt) it grows without bound as ``s → 0``.
"""

from __future__ import annotations

from otmm_qp.exceptions import ParameterError


def _ratio(s: float, sigma_s: float) -> float:
    return min(max(s / sigma_s, 0.0), 1.0)


def linear(s: float, sigma_s: float) -> float:
    """``p = 1 − s/σ_S``."""
    return 1.0 - _ratio(s, sigma_s)


def sqrt(s: float, sigma_s: float) -> float:
    """``p = 1 − (s/σ_S)^(1/2)``."""
    return 1.0 - _ratio(s, sigma_s) ** 0.5


def cbrt(s: float, sigma_s: float) -> float:
    """``p = 1 − (s/σ_S)^(1/3)``."""
    return 1.0 - _ratio(s, sigma_s) ** (1.0 / 3.0)


def power(s: float, sigma_s: float, a: float = 1.0) -> float:
    """``p = 1 − (s/σ_S)^a`` with exponent ``a > 0``."""
    if not a > 0.0:
        raise ParameterError("a", f"exponent must be > 0, got {a}")
    return 1.0 - _ratio(s, sigma_s) ** a
