"""Which schema a file without ``version:`` is written in: the keys that exist in only one.

A key is evidence of schema 1 when schema 1 had it and the current schema does not (a name
change of :data:`~otmm_qp.migration.changes.CHANGES`: ``limit_gain`` of qp), and evidence of
schema 2 when the current schema has it and schema 1 did not (qp's ``regularization``, a
pose_circle's ``profile``, a plugin type otmm-qp ships since 0.2). A plugin type otmm-qp does
not ship (a third-party or misspelt one) is evidence of nothing, and neither are its keys: it
may have existed under either schema.

What schema 1 had is the frozen table of :mod:`otmm_qp.migration.versions`; what the current
schema has is read from the installed code (the config models' fields and the parameters of
the plugins otmm-qp ships) through a :class:`CurrentSchema` the caller passes
(:data:`otmm_qp.config.current_schema.CURRENT_SCHEMA`), so this package imports neither the
config models nor the registry (both sit above it). When schema 3 comes, schema 2's keys are
frozen as schema 1's are.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol

__all__ = ["CurrentSchema", "block_evidence", "record_evidence"]


class CurrentSchema(Protocol):
    """What the current schema has: record keys by level, the parameters of shipped plugins."""

    def record_keys(self, level: str) -> frozenset[str]:
        """The keys a record of ``level`` (``file``, ``experiments``, ``controllers``) takes."""
        ...

    def shipped_parameters(self, group: str, kind: str) -> frozenset[str] | None:
        """The parameters of otmm-qp's plugin ``kind`` of ``group``; None: not shipped."""
        ...


def record_evidence(
    current: CurrentSchema,
    level: str,
    record: Mapping[str, Any],
    path: str,
    schema_1: frozenset[str],
) -> dict[int, list[str]]:
    """The keys of one record (file, experiment, controller) that exist in only one schema."""
    now = current.record_keys(level)
    found: dict[int, list[str]] = {1: [], 2: []}
    for key in record:
        where = f"{path}.{key}" if path else str(key)
        if key in schema_1 and key not in now:
            found[1].append(where)
        elif key not in schema_1 and key in now and key != "version":
            found[2].append(where)
    return found


def block_evidence(
    current: CurrentSchema,
    group: str,
    block: Mapping[str, Any],
    path: str,
    schema_1: Mapping[str, set[str]],
) -> dict[int, list[str]]:
    """The keys (or the type) of one plugin block that exist in only one schema.

    Args:
        current: What the current schema has.
        group: The registry group, last part.
        block: ``{type: NAME, **params}``.
        path: Where the block is, for the evidence text.
        schema_1: Schema 1's plugin types of ``group`` → their parameters.
    """
    kind = str(block.get("type"))
    before = schema_1.get(kind)
    now = current.shipped_parameters(group, kind)
    found: dict[int, list[str]] = {1: [], 2: []}
    if before is None and now is not None:
        found[2].append(f"{path}.type: {kind}")
    elif before is not None and now is not None:
        for key in block:
            if key in before and key not in now:
                found[1].append(f"{path}.{key}")
            elif key not in before and key in now:
                found[2].append(f"{path}.{key}")
    return found
