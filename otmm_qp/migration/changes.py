r"""Every change of a config key's meaning, default or name between schema versions: one table.

A run or study file states the schema it is written in with ``version: N``
(:data:`CURRENT_VERSION` is written by every config the project emits). Each row of
:data:`CHANGES` is one key of one kind of plugin block whose meaning changed in schema
``version``, with what it meant, what it means now and a converter that rewrites a block of
the older schema into the current one with the same numbers. The loader refuses, in one line
listing every affected key of the file with its own values, a file that does not state its
version where a key changed meaning (:mod:`otmm_qp.migration.versions`); ``otmm-qp migrate``
applies the converters.

=====  ========================  ============  =================================================
kind   key (blocks)              schema        what changed
=====  ========================  ============  =================================================
value  ``damping`` (qp, pink,    1 → 2         μ, the QP's Tikhonov weight (μ = λ²) → λ, the DLS
       mink)                                   damping factor; μ is ``regularization``
value  ``profile`` absent        1 → 2         constant speed → quintic (rest to rest), the end
       (pose_circle)                           pose held after ``turns·period``
value  ``limits`` absent or true 1 → 2         mink's ConfigurationLimit gain 0.95 → gain 0.5
       (mink)
value  ``limits`` absent         1 → 2         Drake's position limits outright (gain 1) →
       (drake)                                 gain 0.5
name   ``limit_gain``,           2             one ``limits: [...]`` list
       ``acceleration_limit``,
       ``singularity_barrier``,
       ``max_speed`` (sns)
name   ``posture_weight``,       2             one ``posture: {weight, gain, q_nominal}`` block
       ``posture_gain``,
       ``q_nominal`` (qp)
name   ``damping_floor``,        2             ``lambda_sq_floor``, ``max_lambda_sq`` (they are
       ``max_damping``                         λ², the same numbers)
name   ``solver: direct_*``      2             ``daqp``, ``osqp``, ``proxsuite``
=====  ========================  ============  =================================================

A *value* change is refused only where the file does not say it is written in the current
schema; a *name* change (the key no longer exists) is refused in every file.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Literal

__all__ = [
    "CHANGES",
    "CURRENT_VERSION",
    "RELEASES",
    "Block",
    "SchemaChange",
]

#: The schema version of the current release; written as ``version:`` by every emitted config.
CURRENT_VERSION = 2

#: What each schema version is.
RELEASES: Mapping[int, str] = {1: "otmm-qp 0.1.0", 2: "otmm-qp 0.2"}

#: A plugin block ``{type: NAME, **params}`` as read from YAML.
Block = dict[str, Any]


@dataclass(frozen=True)
class SchemaChange:
    """One key of one kind of plugin block whose meaning, default or name changed.

    Attributes:
        version: The first schema version with the new meaning.
        group: The blocks' registry group, last part (``backends``, ``trajectories``).
        types: The plugin types (``type:``) the change concerns.
        key: The parameter.
        kind: ``value`` (the key or its absence means another number now) or ``name`` (the
            key is gone: renamed, moved or replaced).
        was: What the key (or its absence) meant before ``version``.
        now: What it means since ``version``.
        convert: The block rewritten in the current schema with the same numbers (a new
            dict; keys of other changes untouched).
        applies: Whether a block is concerned (default: the key is present).
        also: Another way to write it, from the block's values (e.g. ``damping: √μ``).
    """

    version: int
    group: str
    types: tuple[str, ...]
    key: str
    kind: Literal["value", "name"]
    was: str
    now: str
    convert: Callable[[Block], Block]
    applies: Callable[[Mapping[str, Any]], bool] | None = None
    also: Callable[[Mapping[str, Any]], str] | None = None

    def concerns(self, group: str, block: Mapping[str, Any]) -> bool:
        """Whether this change concerns ``block``, a block of registry group ``group``."""
        if group != self.group or block.get("type") not in self.types:
            return False
        return self.applies(block) if self.applies is not None else self.key in block


def _renamed(old: str, new: str) -> Callable[[Block], Block]:
    """The converter of a key renamed with the same number."""

    def convert(block: Block) -> Block:
        out = {key: value for key, value in block.items() if key != old}
        if old in block:
            out[new] = block[old]
        return out

    return convert


def _sqrt_damping(block: Mapping[str, Any]) -> str:
    value = block.get("damping")
    if isinstance(value, int | float) and not isinstance(value, bool) and value >= 0:
        return f"damping: {math.sqrt(value):.6g} (λ = √μ)"
    return "damping: √μ"


#: Older limit keys → (limit type, its parameter); the value of singularity_barrier is a mapping.
_LIMIT_KEYS = {
    "max_speed": ("velocity", "max_speed"),
    "limit_gain": ("position", "gain"),
    "acceleration_limit": ("acceleration", "a_max"),
    "singularity_barrier": ("singularity_barrier", None),
}
#: The gain of each backend's default position limit (a ``limits`` list replaces it).
_DEFAULT_GAIN = {"sns": 1.0}


def _limits_list(block: Block) -> Block:
    """Every older limit key of ``block`` as one ``limits`` list (the order the backend used)."""
    given = {key: block[key] for key in _LIMIT_KEYS if key in block}
    if not given:
        return dict(block)
    out = {key: value for key, value in block.items() if key not in _LIMIT_KEYS}
    entries: list[dict[str, Any]] = []
    if "max_speed" in given:
        entries.append({"type": "velocity", "max_speed": given["max_speed"]})
    gain = given.get("limit_gain", _DEFAULT_GAIN.get(str(block.get("type")), 0.5))
    entries.append({"type": "position", "gain": gain})
    if "acceleration_limit" in given:
        entries.append({"type": "acceleration", "a_max": given["acceleration_limit"]})
    barrier = given.get("singularity_barrier")
    if isinstance(barrier, Mapping):
        entries.append({"type": "singularity_barrier", **barrier})
    elif barrier is not None:
        entries.append({"type": "singularity_barrier"})
    out["limits"] = entries
    return out


def _posture_block(block: Block) -> Block:
    """``posture_weight``, ``posture_gain``, ``q_nominal`` as one ``posture`` block."""
    moved = {"posture_weight": "weight", "posture_gain": "gain", "q_nominal": "q_nominal"}
    out = {key: value for key, value in block.items() if key not in moved}
    posture = {new: block[old] for old, new in moved.items() if old in block}
    if posture:
        out["posture"] = {**posture, **dict(block.get("posture") or {})}
    return out


#: Solver names of schema 1 → their current names.
_SOLVER_NAMES = {"direct_daqp": "daqp", "direct_osqp": "osqp", "direct_proxsuite": "proxsuite"}


def _solver_name(block: Block) -> Block:
    solver = block.get("solver")
    new = _SOLVER_NAMES.get(solver) if isinstance(solver, str) else None
    return {**block, "solver": new} if new is not None else dict(block)


def _explicit_limits(gain: float) -> Callable[[Block], Block]:
    """The converter writing a peer's schema-1 limits as the list: speed and position ``gain``."""

    def convert(block: Block) -> Block:
        entries = [{"type": "velocity"}, {"type": "position", "gain": gain}]
        return {**block, "limits": entries}

    return convert


_QP_LIMITS = ("qp", "qp_scaled", "qp_manipulability")
_PEERS = ("pink", "mink", "drake")


def _limit_change(key: str, types: tuple[str, ...]) -> SchemaChange:
    kind, parameter = _LIMIT_KEYS[key]
    entry = f"{{type: {kind}, {parameter}: …}}" if parameter else f"{{type: {kind}, …}}"
    return SchemaChange(
        2,
        "backends",
        types,
        key,
        "name",
        f"the {kind} limit of the backend",
        f"removed (limits have one form: {entry} in one limits list, replacing the default set)",
        _limits_list,
    )


#: Every change, oldest first (a new row per later change: the loader and ``migrate`` read it).
CHANGES: tuple[SchemaChange, ...] = (
    SchemaChange(
        2,
        "backends",
        ("qp", "pink", "mink"),
        "damping",
        "value",
        "μ, the Tikhonov weight of the QP cost (μ = λ²)",
        "λ, the damping factor of Jᵀ(JJᵀ + λ²I)⁻¹ as in every backend; μ is regularization",
        _renamed("damping", "regularization"),
        also=_sqrt_damping,
    ),
    SchemaChange(
        2,
        "trajectories",
        ("pose_circle",),
        "profile",
        "value",
        "constant speed from t = 0, circling on past turns·period",
        "quintic (starting and ending at rest), the end pose held after turns·period",
        lambda block: {**block, "profile": "constant"},
        applies=lambda block: "profile" not in block,
        also=lambda block: "profile: quintic (the current default)",
    ),
    SchemaChange(
        2,
        "backends",
        ("mink",),
        "limits",
        "value",
        "absent or true: mink's own ConfigurationLimit gain 0.95 and the speed limits",
        "absent or true: the default set, position gain 0.5 and the speed limits",
        _explicit_limits(0.95),
        applies=lambda block: block.get("limits", True) is True,
        also=lambda block: "limits: true (the current default, gain 0.5)",
    ),
    SchemaChange(
        2,
        "backends",
        ("drake",),
        "limits",
        "value",
        "absent: Drake held the joints inside their position limits outright (gain 1)",
        "absent: the default set, position gain 0.5 and the speed limits",
        _explicit_limits(1.0),
        applies=lambda block: "limits" not in block,
        also=lambda block: "limits: true (the current default, gain 0.5)",
    ),
    _limit_change("limit_gain", _QP_LIMITS + _PEERS),
    _limit_change("acceleration_limit", _QP_LIMITS),
    _limit_change("singularity_barrier", ("qp",)),
    _limit_change("max_speed", ("sns",)),
    *(
        SchemaChange(
            2,
            "backends",
            ("qp",),
            key,
            "name",
            f"the posture cost's {new}",
            f"moved into posture: {{weight, gain, q_nominal}} (its {new})",
            _posture_block,
        )
        for key, new in (
            ("posture_weight", "weight"),
            ("posture_gain", "gain"),
            ("q_nominal", "q_nominal"),
        )
    ),
    *(
        SchemaChange(
            2,
            "backends",
            types,
            old,
            "name",
            f"{old}, a λ² [task units²/rad²] named like a damping factor",
            f"renamed to {new}, the same number (it is λ² [task units²/rad²])",
            _renamed(old, new),
        )
        for old, new, types in (
            ("damping_floor", "lambda_sq_floor", ("dls_error", "sigma_lm")),
            ("max_damping", "max_lambda_sq", ("dls_error",)),
        )
    ),
    SchemaChange(
        2,
        "backends",
        ("qp",),
        "solver",
        "name",
        "direct_daqp / direct_osqp / direct_proxsuite: the persistent sessions",
        "renamed: the persistent sessions are daqp, osqp, proxsuite",
        _solver_name,
        applies=lambda block: block.get("solver") in _SOLVER_NAMES,
    ),
)
