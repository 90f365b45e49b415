r"""The one YAML form of limits, and the one mapping of the older per-backend keys onto it.

A backend that enforces limits takes ``limits``, a list of registered limits
(entry-point group ``otmm_qp.limits``)::

    backend: {type: qp, limits: [{type: position, gain: 0.5}, {type: acceleration, a_max: 50}]}

Limits are instances or mappings ``{type: NAME, **params}``. The robot's speed limit
(``velocity``) always applies: it is added when the list has none (list
``{type: velocity, max_speed: 1.0}`` to cap it further). Without ``limits`` a backend uses its
default set, ``velocity`` and ``position`` (gain 0.5 for ``qp``, ``qp_scaled`` and the peers,
1 for ``sns``).

The older keys keep working and are mapped here (:data:`LEGACY_KEYS`), and only here:

========================  ==============================================
older key                 the same limit in the ``limits`` form
========================  ==============================================
``limit_gain: g``         ``{type: position, gain: g}``
``acceleration_limit: a`` ``{type: acceleration, a_max: a}``
``max_speed: s``          ``{type: velocity, max_speed: s}``
``singularity_barrier:``  ``{type: singularity_barrier, sigma_safe: …, gain: …}``
========================  ==============================================

Giving ``limits`` together with an older key is refused with one line saying what to write.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from numbers import Real
from typing import Any, NamedTuple

from otmm_qp.exceptions import ConfigError, ParameterError
from otmm_qp.limits.limit import BaseLimit, Limit, RowLimit
from otmm_qp.limits.velocity_limit import VelocityLimit
from otmm_qp.validation import ArrayOf, Constraints, InstanceOf, Interval

__all__ = [
    "FIELD",
    "LEGACY_CONSTRAINTS",
    "LEGACY_KEYS",
    "LIMITS",
    "LimitSet",
    "LimitSpec",
    "make_limits",
]

#: The config key of the limits list.
FIELD = "limits"

#: Older key → (limit type, its parameter; None: the value is the mapping of parameters).
LEGACY_KEYS: dict[str, tuple[str, str | None]] = {
    "limit_gain": ("position", "gain"),
    "acceleration_limit": ("acceleration", "a_max"),
    "max_speed": ("velocity", "max_speed"),
    "singularity_barrier": ("singularity_barrier", None),
}

#: What a ``limits`` entry may be: a limit object or ``{type: NAME, **params}``.
LimitSpec = BaseLimit | Mapping[str, Any]

#: The declared constraint of a backend's ``limits`` parameter (each entry is checked by
#: :func:`make_limits`, naming ``limits.<i>``).
LIMITS = InstanceOf(
    (Sequence,), "a list of {type: NAME, ...} entries", exclude=(str, bytes, Mapping)
)

#: The declared constraints of the older keys (each backend declares the ones it takes).
LEGACY_CONSTRAINTS: Constraints = {
    "limit_gain": [Interval(Real, 0, 1, closed="right"), None],
    "acceleration_limit": [
        ArrayOf(
            Interval(Real, 0, None, closed="neither", unit="rad/s²", inf_ok=True),
            scalar=True,
            per="joint",
        ),
        None,
    ],
    "max_speed": [Interval(Real, 0, None, closed="neither", unit="rad/s"), None],
    "singularity_barrier": [
        InstanceOf((Mapping, BaseLimit), "a mapping {sigma_safe: ..., gain: ...}"),
        None,
    ],
}


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


def make_limits(
    limits: Sequence[LimitSpec] | None,
    legacy: Mapping[str, Any] | None = None,
    default_gain: float = 0.5,
) -> LimitSet:
    """The limits of a backend from its ``limits`` option or its older keys.

    Args:
        limits: The ``limits`` list, or None for the default set.
        legacy: Older keys given to the backend, by name (None values are ignored).
        default_gain: The position gain of the default set.

    Raises:
        ConfigError: An unknown limit type or parameter, a malformed entry, a value out of
            range (field ``limits.<i>.<param>`` or the older key), or ``limits`` given
            together with an older key.
    """
    given = {key: value for key, value in (legacy or {}).items() if value is not None}
    unknown = sorted(set(given) - set(LEGACY_KEYS))
    if unknown:
        raise ParameterError(unknown[0], f"not a limit key; allowed: {', '.join(LEGACY_KEYS)}")
    if limits is not None:
        if given:
            key = next(iter(given))
            kind, param = LEGACY_KEYS[key]
            entry = f"{{type: {kind}, {param}: ...}}" if param else f"{{type: {kind}, ...}}"
            raise ParameterError(key, f"give it inside {FIELD} ({FIELD}: [..., {entry}]), not both")
        if isinstance(limits, str | bytes | Mapping) or not isinstance(limits, Sequence):
            raise ParameterError(
                FIELD, f"must be a list of {{type: NAME, ...}} entries, got {limits!r:.40}"
            )
        made = [_make(entry, f"{FIELD}.{i}") for i, entry in enumerate(limits)]
    else:
        made = _from_legacy(given, default_gain)
    boxes = [limit for limit in made if isinstance(limit, Limit)]
    if not any(isinstance(limit, VelocityLimit) for limit in boxes):
        boxes.insert(0, VelocityLimit())
    rows = [limit for limit in made if isinstance(limit, RowLimit)]
    return LimitSet(tuple(boxes), tuple(rows))


def _from_legacy(given: Mapping[str, Any], default_gain: float) -> list[BaseLimit]:
    """The default set with the older keys applied (errors name the older key)."""
    speed = {"max_speed": given["max_speed"]} if "max_speed" in given else {}
    gain = {"gain": given.get("limit_gain", default_gain)}
    made = [
        _legacy_entry("velocity", speed, "max_speed"),
        _legacy_entry("position", gain, "limit_gain"),
    ]
    if "acceleration_limit" in given:
        a_max = {"a_max": given["acceleration_limit"]}
        made.append(_legacy_entry("acceleration", a_max, "acceleration_limit"))
    barrier = given.get("singularity_barrier")
    if isinstance(barrier, BaseLimit):
        made.append(barrier)
    elif barrier is not None:
        if not isinstance(barrier, Mapping):
            raise ParameterError(
                "singularity_barrier",
                f"must be a mapping with sigma_safe, gain; got {barrier!r:.40}",
            )
        made.append(_legacy_entry("singularity_barrier", dict(barrier), "singularity_barrier"))
    return made


def _legacy_entry(kind: str, params: dict[str, Any], key: str) -> BaseLimit:
    """A limit from an older key; a bad value names that key (``key.param`` for a mapping)."""
    try:
        return _make({"type": kind, **params}, key)
    except ConfigError as error:
        field = error.field
        if LEGACY_KEYS[key][1] is not None:  # a scalar key: the value *is* the parameter
            field = key
        raise ParameterError(field, error.message) from error


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
