"""Which schema a file without ``version:`` is written in: the keys that exist in only one.

A key is evidence of schema 1 when schema 1 had it and the current schema does not (a name
change of :data:`~otmm_qp.migration.changes.CHANGES`: ``limit_gain`` of qp), and evidence of
schema 2 when the current schema has it and schema 1 did not (qp's ``regularization``, a
pose_circle's ``profile``, a plugin type otmm-qp ships since 0.2). A plugin type otmm-qp does
not ship (a third-party or misspelt one) is evidence of nothing, and neither are its keys: it
may have existed under either schema.

What schema 1 had is the frozen table of :mod:`otmm_qp.migration.versions`; what the current
schema has is read from the installed code (the config models' fields and the parameters of
the plugins otmm-qp ships), imported when first asked, so the package stays importable by the
registry without a cycle. When schema 3 comes, schema 2's keys are frozen as schema 1's are.
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping
from functools import cache
from typing import Any

#: The packages whose plugins are otmm-qp's own (the rest are third-party).
SHIPPED_PACKAGES = ("otmm_qp", "otmm_qp_controllers")
#: Record levels of a run file → the config model holding their keys today.
_RECORD_MODELS = {
    "file": "SuiteConfig",
    "experiments": "ExperimentConfig",
    "controllers": "ControllerConfig",
}


@cache
def record_keys(level: str) -> frozenset[str]:
    """The keys a record of ``level`` (``file``, ``experiments``, ``controllers``) takes today."""
    from otmm_qp.config import schema

    model = getattr(schema, _RECORD_MODELS[level])
    keys = set(model.model_fields)
    keys |= {f.alias for f in model.model_fields.values() if f.alias}
    return frozenset(keys)


@cache
def shipped_parameters(group: str, kind: str) -> frozenset[str] | None:
    """The parameters otmm-qp's plugin ``kind`` of registry group ``group`` takes today.

    Args:
        group: The registry group, last part (``backends``).
        kind: The plugin type.

    Returns:
        The parameter names, or None when otmm-qp does not ship ``kind`` (a third-party,
        unknown or broken plugin: no evidence either way; it is not imported).
    """
    from otmm_qp import registry
    from otmm_qp.exceptions import OtmmError

    try:
        spec = registry.specs(f"otmm_qp.{group}").get(kind)
        if spec is None or spec.value.split(".")[0].split(":")[0] not in SHIPPED_PACKAGES:
            return None
        factory = registry.load(spec.group, kind)
        signature = inspect.signature(factory)
    except (OtmmError, TypeError, ValueError):
        return None
    return frozenset(
        p.name
        for p in signature.parameters.values()
        if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and p.name != "self"
    )


def record_evidence(
    level: str, record: Mapping[str, Any], path: str, schema_1: frozenset[str]
) -> dict[int, list[str]]:
    """The keys of one record (file, experiment, controller) that exist in only one schema."""
    now = record_keys(level)
    found: dict[int, list[str]] = {1: [], 2: []}
    for key in record:
        where = f"{path}.{key}" if path else str(key)
        if key in schema_1 and key not in now:
            found[1].append(where)
        elif key not in schema_1 and key in now and key != "version":
            found[2].append(where)
    return found


def block_evidence(
    group: str, block: Mapping[str, Any], path: str, schema_1: Mapping[str, set[str]]
) -> dict[int, list[str]]:
    """The keys (or the type) of one plugin block that exist in only one schema.

    Args:
        group: The registry group, last part.
        block: ``{type: NAME, **params}``.
        path: Where the block is, for the evidence text.
        schema_1: Schema 1's plugin types of ``group`` → their parameters.
    """
    kind = str(block.get("type"))
    before = schema_1.get(kind)
    now = shipped_parameters(group, kind)
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
