"""The one number formatter of the study's Markdown (report, fronts, trade-off).

``–`` stands for a value that is not finite (no rows, no test).
"""

from __future__ import annotations

import math

from otmm_qp.studies.statistics import Interval, significant_digits

#: What a non-finite value prints as.
MISSING = "–"


def fmt(value: float, digits: int = 3) -> str:
    """``value`` with ``digits`` significant digits (``g`` format), or :data:`MISSING`."""
    return f"{value:.{digits}g}" if math.isfinite(value) else MISSING


def p_value(value: float) -> str:
    """A p-value with two significant digits, or :data:`MISSING`."""
    return fmt(value, 2)


def percent(value: float) -> str:
    """A fraction in [0, 1] as a whole percentage ``NN %``, or :data:`MISSING`."""
    return f"{100 * value:.0f} %" if math.isfinite(value) else MISSING


def interval(value: Interval) -> str:
    """``value [low, high]``; the endpoints with only the digits their Monte-Carlo error fixes."""
    digits = [significant_digits(e, value.mc_error) for e in (value.low, value.high)]
    return f"{fmt(value.value)} [{fmt(value.low, digits[0])}, {fmt(value.high, digits[1])}]"
