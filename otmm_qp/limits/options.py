r"""The one YAML form of limits, and the one place that answers the older per-backend keys.

A backend that enforces limits takes ``limits``, a list of registered limits
(entry-point group ``otmm_qp.limits``)::

    backend: {type: qp, limits: [{type: position, gain: 0.5}, {type: acceleration, a_max: 50}]}

Limits are instances or mappings ``{type: NAME, **params}``. The robot's speed limit
(``velocity``) always applies: it is added when the list has none (list
``{type: velocity, max_speed: 1.0}`` to cap it further). Without ``limits`` a backend uses its
default set, ``velocity`` and ``position`` (gain 0.5 for ``qp``, ``qp_scaled`` and the peers,
1 for ``sns``).

Backend constructors take ``limits`` only. The older keys are refused, each with one line
that says what to write instead (:func:`removed_limit_keys`, read by the registry before a
backend is built, from the backend's ``removed_parameters``):

========================  ==============================================================
older key                 the same limits in the ``limits`` form
========================  ==============================================================
``limit_gain: g``         ``[{type: position, gain: g}]``
``acceleration_limit: a`` ``[{type: position, gain: 0.5}, {type: acceleration, a_max: a}]``
``max_speed: s`` (sns)    ``[{type: velocity, max_speed: s}, {type: position, gain: 1}]``
``singularity_barrier:``  ``[{type: position, gain: 0.5}, {type: singularity_barrier, …}]``
========================  ==============================================================

(the position entry is the backend's default position limit, which a ``limits`` list replaces;
the velocity limit is always added.)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

from otmm_qp.exceptions import ParameterError
from otmm_qp.limits.limit import BaseLimit, Limit, RowLimit
from otmm_qp.limits.predicted_position_limit import PredictedPositionLimit
from otmm_qp.limits.velocity_limit import VelocityLimit
from otmm_qp.validation import InstanceOf

__all__ = [
    "FIELD",
    "LEGACY_KEYS",
    "LIMITS",
    "LimitSet",
    "LimitSpec",
    "make_limits",
    "removed_limit_keys",
]

#: The config key of the limits list.
FIELD = "limits"

#: Older key → the entry of the ``limits`` list that replaces it.
LEGACY_KEYS: dict[str, str] = {
    "limit_gain": "{type: position, gain: G}",
    "acceleration_limit": "{type: acceleration, a_max: A}",
    "max_speed": "{type: velocity, max_speed: S}",
    "singularity_barrier": "{type: singularity_barrier, sigma_safe: S, gain: G}",
}

#: What a ``limits`` entry may be: a limit object or ``{type: NAME, **params}``.
LimitSpec = BaseLimit | Mapping[str, Any]

#: The declared constraint of a backend's ``limits`` parameter (each entry is checked by
#: :func:`make_limits`, naming ``limits.<i>``).
LIMITS = InstanceOf(
    (Sequence,), "a list of {type: NAME, ...} entries", exclude=(str, bytes, Mapping)
)


class LimitSet(NamedTuple):
    """A backend's limits, split by kind.

    Attributes:
        boxes: The box limits (a :class:`VelocityLimit` always among them).
        rows: The row limits (e.g. the singularity barrier).
    """

    boxes: tuple[Limit, ...]
    rows: tuple[RowLimit, ...]

    @property
    def all(self) -> tuple[BaseLimit, ...]:
        """Every limit, boxes first."""
        return (*self.boxes, *self.rows)


def removed_limit_keys(*keys: str, default_gain: float = 0.5) -> dict[str, str]:
    """The one-line refusals of older limit keys, for a backend's ``removed_parameters``.

    Args:
        *keys: Older keys of :data:`LEGACY_KEYS` the backend once took.
        default_gain: The gain of the backend's default position limit (a ``limits`` list
            replaces the default set, so the message lists it).

    Returns:
        ``{key: "removed in 0.2 (limits have one form): write limits: [...] instead ..."}``.
    """
    position = f"{{type: position, gain: {default_gain:g}}}"
    refusals = {}
    for key in keys:
        entry = LEGACY_KEYS[key]
        if key == "limit_gain":
            listed = entry
        elif key == "max_speed":
            listed = f"{entry}, {position}"
        else:
            listed = f"{position}, {entry}"
        refusals[key] = (
            f"removed (limits have one form): write {FIELD}: [{listed}] instead "
            "(the velocity limit is always added)"
        )
    return refusals


def make_limits(limits: Sequence[LimitSpec] | None, default_gain: float = 0.5) -> LimitSet:
    """The limits of a backend from its ``limits`` option.

    Args:
        limits: The ``limits`` list, or None for the default set: ``velocity`` and
            ``{type: position, gain: default_gain}``.
        default_gain: The position gain of the default set.

    Raises:
        ConfigError: An unknown limit type or parameter, a malformed entry or a value out of
            range (field ``limits.<i>.<param>``).
    """
    if limits is not None:
        if isinstance(limits, str | bytes | Mapping) or not isinstance(limits, Sequence):
            raise ParameterError(
                FIELD, f"must be a list of {{type: NAME, ...}} entries, got {limits!r:.40}"
            )
        made = [_make(entry, f"{FIELD}.{i}") for i, entry in enumerate(limits)]
    else:
        made = [VelocityLimit(), PredictedPositionLimit(default_gain)]
    boxes = [limit for limit in made if isinstance(limit, Limit)]
    if not any(isinstance(limit, VelocityLimit) for limit in boxes):
        boxes.insert(0, VelocityLimit())
    rows = [limit for limit in made if isinstance(limit, RowLimit)]
    return LimitSet(tuple(boxes), tuple(rows))


def _make(entry: LimitSpec, field: str) -> BaseLimit:
    """One limit from an instance or ``{type: NAME, **params}``."""
    if isinstance(entry, BaseLimit):
        return entry
    if not isinstance(entry, Mapping) or "type" not in entry:
        raise ParameterError(field, f"must be a mapping {{type: NAME, ...}}, got {entry!r:.40}")
    from otmm_qp import registry  # the registry imports the base classes lazily

    params = {key: value for key, value in entry.items() if key != "type"}
    limit: BaseLimit = registry.create(registry.LIMITS, str(entry["type"]), params, field)
    return limit
