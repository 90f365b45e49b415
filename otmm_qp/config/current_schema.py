"""What the current schema has, read from the installed code, for inferring a file's schema.

:mod:`otmm_qp.migration.evidence` compares a file's keys with schema 1's frozen table and with
this: the config models' fields (by record level) and the parameters of the plugins otmm-qp
ships. It lives here, above the registry and the config models, so the migration package
imports neither.
"""

from __future__ import annotations

import inspect
from functools import cache

from pydantic import BaseModel

from otmm_qp import registry
from otmm_qp.config import schema
from otmm_qp.exceptions import OtmmError

__all__ = ["CURRENT_SCHEMA", "InstalledSchema", "SHIPPED_PACKAGES"]

#: The packages whose plugins are otmm-qp's own (the rest are third-party).
SHIPPED_PACKAGES = ("otmm_qp", "otmm_qp_controllers")
#: Record levels of a run file → the config model holding their keys today.
_RECORD_MODELS: dict[str, type[BaseModel]] = {
    "file": schema.SuiteConfig,
    "experiments": schema.ExperimentConfig,
    "controllers": schema.ControllerConfig,
}


class InstalledSchema:
    """The current schema of the installed otmm-qp (a :class:`~.evidence.CurrentSchema`)."""

    @staticmethod
    @cache
    def record_keys(level: str) -> frozenset[str]:
        """The keys a record of ``level`` (``file``, ``experiments``, ``controllers``) takes."""
        model = _RECORD_MODELS[level]
        keys = set(model.model_fields)
        keys |= {f.alias for f in model.model_fields.values() if f.alias}
        return frozenset(keys)

    @staticmethod
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


#: The one instance callers pass to :func:`otmm_qp.migration.versions.read_schema` & co.
CURRENT_SCHEMA = InstalledSchema()
