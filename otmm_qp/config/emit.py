"""The one writer of config files the project emits: YAML with ``version:`` first."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from otmm_qp.migration.versions import versioned

__all__ = ["dump_config", "write_config"]


def dump_config(record: Mapping[str, Any]) -> str:
    """``record`` as YAML text, ``version: CURRENT_VERSION`` first, keys in their order.

    Floats are written by ``repr``, so they read back bit for bit; leaf lists and mappings in
    flow style (``q0: [0.0, -0.3]``).
    """
    return yaml.safe_dump(
        versioned(record), sort_keys=False, allow_unicode=True, default_flow_style=None, width=100
    )


def write_config(path: Path, record: Mapping[str, Any]) -> None:
    """Write ``record`` to ``path`` atomically (:func:`dump_config`)."""
    from otmm_qp.paths import atomic_write_text

    atomic_write_text(path, dump_config(record))
