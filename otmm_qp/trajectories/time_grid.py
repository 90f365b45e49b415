r"""Times compared as integers: which piece of a piecewise trajectory holds at ``t``.

A control loop samples at :math:`t_k = k\,dt`; a piecewise trajectory switches at
:math:`T_i = \sum_{j<i} h_j`. Compared as floats, the two disagree by an ulp where the user means
one instant (``hold: 0.1`` at ``dt = 0.02``: ``T_3 = 0.30000000000000004 > t_15 = 0.3``, so the
switch came a step late). Here every time is an integer count of :data:`TICK` (1 ns): ``T_i`` is
the exact integer sum of the rounded ``h_j`` and ``t`` is rounded once, so a boundary and a
sample time that are equal in decimal are equal. Python integers: no overflow for any finite
duration.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from fractions import Fraction

__all__ = ["TICK", "piece_index", "start_ticks", "ticks"]

#: The time quantum [s] times are rounded to before they are compared.
TICK = 1e-9
_PER_SECOND = 10**9


def ticks(seconds: float) -> int:
    """``round(seconds / TICK)``: a finite time [s] as an integer number of ticks.

    Exact beyond the float range too (``1e300`` s).
    """
    value = float(seconds)
    scaled = value * _PER_SECOND
    return round(scaled) if math.isfinite(scaled) else round(Fraction(value) * _PER_SECOND)


def start_ticks(durations: Sequence[float]) -> list[int]:
    """Start of each piece in ticks: ``[0, h_0, h_0 + h_1, ...]`` (each ``h_j`` rounded once)."""
    starts = [0]
    for duration in durations[:-1]:
        starts.append(starts[-1] + ticks(duration))
    return starts


def piece_index(starts: Sequence[int], t: float) -> int:
    """Index of the piece holding at ``t`` [s]: the last start ≤ ``t`` (0 before the first)."""
    return max(0, bisect.bisect_right(starts, ticks(t)) - 1)
