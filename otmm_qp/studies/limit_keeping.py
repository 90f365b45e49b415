"""Whether a study row keeps the arm's limits: the speed and position-limit success criteria.

An episode *breaks the limits* when it fails the study's speed criterion (each joint within
``joint_speed_factor`` × its own velocity limit, or the absolute ``max_joint_speed``) or its
position-limit criterion (``no_limit_violation``): its ``failure_causes`` hold ``speed`` or
``position_limit``. A "most accurate" pick names how often its row did, in the same line, so
that an accurate row that gets its accuracy by exceeding the arm's limits is never
recommended silently.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

__all__ = ["LIMIT_CAUSES", "breaks_clause", "limit_breaks", "limits_clause"]

#: Failure causes that mean the arm's limits were not kept.
LIMIT_CAUSES = ("speed", "position_limit")


def limit_breaks(rows: Iterable[dict[str, Any]], controller: str) -> tuple[int, int]:
    """``(episodes of controller breaking the limits, its episodes)`` among ``rows``."""
    own = [r for r in rows if r.get("controller") == controller]
    broken = sum(1 for r in own if any(c in LIMIT_CAUSES for c in r.get("failure_causes", ())))
    return broken, len(own)


def breaks_clause(broken: int, total: int) -> str:
    """`` (limits broken on broken of total tasks)``, or ``""`` when ``broken`` is 0."""
    return f" (limits broken on {broken} of {total} tasks)" * (broken > 0)


def limits_clause(rows: Iterable[dict[str, Any]], controller: str) -> str:
    """:func:`breaks_clause` of ``controller``'s rows among ``rows``."""
    return breaks_clause(*limit_breaks(rows, controller))
