"""Safe output for replays: the contracts' ``otmm_qp.output.paths`` when present.

Branch hostile-input adds ``otmm_qp.output.paths`` (the one safe-name function, the
inside-the-folder check and atomic writes). Until it is merged, the minimal equivalents
below keep replays inside ``RESULTS_DIR`` and never leave a half-written file.
"""

from __future__ import annotations

import hashlib
import importlib
import os
import re
from pathlib import Path
from typing import Any

from otmm_qp.exceptions import ConfigError


def _paths() -> Any | None:
    try:
        return importlib.import_module("otmm_qp.output.paths")
    except ImportError:
        return None


def safe_name(name: str) -> str:
    """A file-name-safe slug of ``name`` (``[A-Za-z0-9._-]``, never empty, ``.`` or ``..``)."""
    paths = _paths()
    if paths is not None:
        return str(paths.safe_name(name))
    slug = re.sub(r"[^A-Za-z0-9._-]", "_", name.replace("\0", "")).lstrip(".-")
    if len(slug) > 64:
        slug = slug[:55] + "-" + hashlib.sha256(name.encode()).hexdigest()[:8]
    return slug if slug not in ("", ".", "..") else "_"


def ensure_inside(root: Path, path: Path) -> Path:
    """``path`` resolved (symlinks included); an error unless it lies inside ``root``."""
    paths = _paths()
    if paths is not None:
        return Path(paths.ensure_inside(root, path))
    resolved = path.resolve()
    if not resolved.is_relative_to(root.resolve()):
        raise ConfigError("RESULTS_DIR", f"{path} resolves outside {root}; refusing to write")
    return resolved


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write via a temporary file in the same folder and ``os.replace``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    paths = _paths()
    if paths is not None:
        paths.atomic_write_bytes(path, data)
        return
    temporary = path.with_name(f".{path.name}.tmp")
    try:
        temporary.write_bytes(data)
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)
