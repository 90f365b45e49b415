"""Safe output for replays: the one safe-name function and the writers of ``otmm_qp.output.paths``.

Replays write only through these: names slugged by :func:`safe_name`, every target checked by
:func:`ensure_inside` to stay in the results folder, bytes landed atomically.
"""

from __future__ import annotations

from pathlib import Path

from otmm_qp.output import paths
from otmm_qp.output.paths import ensure_inside

__all__ = ["atomic_write_bytes", "ensure_inside", "safe_name"]


def safe_name(name: str) -> str:
    """A file-name-safe slug of ``name`` (:func:`otmm_qp.output.paths.safe_name`)."""
    return paths.safe_name(name)


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Create ``path``'s folder if needed, then write ``data`` atomically."""
    path.parent.mkdir(parents=True, exist_ok=True)
    paths.atomic_write_bytes(path, data)
