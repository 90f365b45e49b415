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

* ``bounded``: :math:`p = \max(p_{base}(s), 1 - G s)`, gain ``(1-p)/σ ≤ G`` (issue 11).

The parameters are declared (:func:`otmm_qp.validation.declare`) and checked once, when the
OTMM filter is built (:func:`check_gain_cap` too), never per step: called directly with
values the declarations refuse, a p-function's result is undefined.
"""

from __future__ import annotations

from numbers import Real

from otmm_qp.exceptions import ParameterError
from otmm_qp.validation import Interval, OneOf, declare


def _ratio(s: float, sigma_s: float) -> float:
    return min(max(s / sigma_s, 0.0), 1.0)


@declare({})
def linear(s: float, sigma_s: float) -> float:
    """``p = 1 − s/σ_S``."""
    return 1.0 - _ratio(s, sigma_s)


@declare({})
def sqrt(s: float, sigma_s: float) -> float:
    """``p = 1 − (s/σ_S)^(1/2)``."""
    return 1.0 - _ratio(s, sigma_s) ** 0.5


@declare({})
def cbrt(s: float, sigma_s: float) -> float:
    """``p = 1 − (s/σ_S)^(1/3)``."""
    return 1.0 - _ratio(s, sigma_s) ** (1.0 / 3.0)


_EXPONENT = Interval(Real, 0, None, closed="neither")


@declare({"a": _EXPONENT})
def power(s: float, sigma_s: float, a: float = 1.0) -> float:
    """``p = 1 − (s/σ_S)^a`` with exponent ``a > 0``."""
    return 1.0 - _ratio(s, sigma_s) ** a


#: Gain cap of ``bounded`` when a config gives none, as a multiple of 1/σ_S: G = 2/σ_S
#: (40 at the paper's σ_S = 0.05; chosen on the paper's E1/E2, see docs/strategies.md).
DEFAULT_GAIN_FACTOR = 2.0
_BASES = {"linear": linear, "sqrt": sqrt, "cbrt": cbrt, "power": power}


def check_gain_cap(max_gain: float, sigma_s: float) -> None:
    r"""The one check of a gain cap against σ_S: :math:`G \ge 1/\sigma_S` (continuity at σ_S).

    Used by ``bounded`` (:func:`check_bounded`) and the direction-aware OTMM filter.

    Args:
        max_gain: G [rad/(task unit)], a finite number > 0.
        sigma_s: σ_S > 0 [task units].

    Raises:
        ParameterError: ``max_gain`` below ``1/σ_S`` (beyond rounding).
    """
    if max_gain * sigma_s < 1.0 - 1e-12:
        raise ParameterError(
            "max_gain",
            f"must be >= 1/sigma_s = {1.0 / sigma_s:.6g} so p is continuous at sigma_s, "
            f"got {max_gain!r}",
        )


def check_bounded(sigma_s: float, max_gain: float | None = None, **_: object) -> None:
    """``bounded``'s cross-parameter check, run once by the filter: :func:`check_gain_cap`."""
    if max_gain is not None:
        check_gain_cap(max_gain, sigma_s)


@declare(
    {
        "max_gain": [Interval(Real, 0, None, closed="neither"), None],
        "base": OneOf(*_BASES),
        "a": _EXPONENT,
    },
    cross_check=check_bounded,
)
def bounded(
    s: float,
    sigma_s: float,
    max_gain: float | None = None,
    base: str = "cbrt",
    a: float = 1.0,
) -> float:
    r"""Bounded-gain p: :math:`p_G(s) = \max(p_{base}(s),\ 1 - G s)` for ``s ≤ σ_S``.

    Gain bound. Along the filtered direction OTMM leaves :math:`(1-p)(u_s^\top\dot x)` of
    the command, which an inverse with :math:`J^+ u_s = v_s/\sigma` turns into the joint
    speed :math:`\dot q_s = \frac{1-p}{\sigma}(u_s^\top\dot x)\,v_s`. Since
    :math:`p_G \ge 1 - G\sigma`,

    .. math:: \|\dot q_s\| = \frac{1-p_G(\sigma)}{\sigma}\,|u_s^\top\dot x|
              \le \frac{G\sigma}{\sigma}\,|u_s^\top\dot x| = G\,|u_s^\top\dot x|,

    for every σ ∈ (0, σ_S]; at σ = 0 exactly :math:`p_G = 1` and nothing is left to invert.
    Where :math:`p_{base} \ge 1 - G\sigma` already (σ near σ_S) ``p_G`` is the base p, so
    the small window error of sqrt/cbrt is kept away from the singularity itself.
    Continuity at σ_S needs :math:`1 - G\sigma_S \le 0 = p_{base}(\sigma_S)`, i.e.
    ``G ≥ 1/σ_S`` (the linear p has exactly ``G = 1/σ_S``).

    Args:
        s: σ_min [task units].
        sigma_s: Threshold σ_S > 0 [task units].
        max_gain: Gain cap G ≥ 1/σ_S [rad/(task unit)]; ``None``: ``2/σ_S``.
        base: Base p: ``linear``, ``sqrt``, ``cbrt`` or ``power``.
        a: Exponent of the ``power`` base (ignored by the others).

    Declared and checked once by the filter (:func:`check_bounded`), not on each call.
    """
    if max_gain is None:
        max_gain = DEFAULT_GAIN_FACTOR / sigma_s
    function = _BASES[base]
    p_base = power(s, sigma_s, a) if function is power else function(s, sigma_s)
    return max(p_base, 1.0 - max_gain * s)
