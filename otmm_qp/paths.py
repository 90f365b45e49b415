"""Safe output paths: the one way a display name becomes a file name, and atomic writes.

Every file otmm-qp writes goes through this module: names are slugged by :func:`safe_name`
(made unique within a folder by :class:`UniqueNames`), the target is checked to stay inside
the results folder by :func:`ensure_inside`, and the bytes land through a temporary file in the
same directory that is fsynced and renamed over the target (:func:`atomic_open`), so a reader
never sees a half-written file and an interrupted write leaves the old file untouched.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import IO, Any

from otmm_qp.exceptions import OutputPathError
from otmm_qp.interrupt import deferred_stop_signals

_UNSAFE = re.compile(r"[^A-Za-z0-9._-]")
_HASH_DIGITS = 8

#: File stems the results folder itself uses; a run or experiment may not take them.
RESERVED_NAMES = ("summary", "comparison", "report", "index", "claims")


def safe_name(name: str, max_length: int = 64) -> str:
    """A file-name-safe slug of ``name``.

    Characters outside ``[A-Za-z0-9._-]`` become ``_`` (NUL and path separators are removed),
    leading ``.`` and ``-`` are stripped, and the result is never ``''``, ``'.'`` or ``'..'``.
    A slug longer than ``max_length`` is cut and gets ``-`` plus an 8-hex-digit hash of the
    original name, so distinct long names stay distinct.

    Args:
        name: Any display name (experiment, controller, suite...).
        max_length: Longest slug returned [characters]; at least 16.

    Returns:
        The slug, 1 to ``max_length`` characters.
    """
    if max_length < 2 * _HASH_DIGITS:
        raise ValueError(f"max_length must be at least {2 * _HASH_DIGITS}, got {max_length}")
    text = str(name).replace("\x00", "").replace("/", "").replace("\\", "")
    slug = _UNSAFE.sub("_", text).lstrip(".-")
    if not slug:  # '', '.', '..', only separators
        slug = "_"
    if len(slug) > max_length:
        digest = hashlib.sha256(str(name).encode("utf-8", "surrogatepass")).hexdigest()
        slug = slug[: max_length - _HASH_DIGITS - 1] + "-" + digest[:_HASH_DIGITS]
    return slug


class UniqueNames:
    """Unique safe file names for the display names of one scope (one folder).

    The first name whose slug is free gets the plain slug; a later, different name whose slug
    collides with an earlier one or with a reserved stem (case-insensitively, for
    case-insensitive file systems) gets ``-2``, ``-3``, ... The same name always maps to the
    same slug.
    """

    def __init__(self, reserved: Iterable[str] = RESERVED_NAMES, max_length: int = 64) -> None:
        self._max_length = max_length
        self._by_name: dict[str, str] = {}
        self._taken: set[str] = {r.lower() for r in reserved}

    def get(self, name: str) -> str:
        """The unique slug of ``name`` in this scope."""
        if name in self._by_name:
            return self._by_name[name]
        base = safe_name(name, self._max_length)
        slug, n = base, 1
        while slug.lower() in self._taken:
            n += 1
            suffix = f"-{n}"
            slug = base[: self._max_length - len(suffix)] + suffix
        self._taken.add(slug.lower())
        self._by_name[name] = slug
        return slug


def unique_names(
    names: Iterable[str], reserved: Iterable[str] = RESERVED_NAMES, max_length: int = 64
) -> dict[str, str]:
    """``{name: unique slug}`` for ``names`` in order (see :class:`UniqueNames`)."""
    scope = UniqueNames(reserved, max_length)
    return {name: scope.get(name) for name in names}


def ensure_inside(root: Path, path: Path) -> Path:
    """Resolve ``path`` (symlinks included) and require it to lie inside ``root``.

    Args:
        root: The results folder.
        path: A path to be read or written (absolute, or relative to the working directory).

    Returns:
        The resolved path.

    Raises:
        OutputPathError: ``path`` resolves outside ``root`` (e.g. via ``..`` or a symlink).
    """
    resolved_root = Path(os.path.realpath(root))
    resolved = Path(os.path.realpath(path))
    if resolved != resolved_root and resolved_root not in resolved.parents:
        shown = str(resolved)[:200]
        raise OutputPathError(str(path), f"resolves to {shown!r}, outside the results folder")
    return resolved


@contextlib.contextmanager
def atomic_open(path: Path, mode: str = "w", newline: str | None = None) -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path``; on success fsync it and rename it over ``path``.

    On any error (including KeyboardInterrupt) the temporary file is removed and an existing
    ``path`` is left untouched.

    Args:
        path: Target file.
        mode: ``"w"`` (text, UTF-8) or ``"wb"``.
        newline: As for :func:`open` (text mode only).
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"atomic_open mode must be 'w' or 'wb', got {mode!r}")
    path = Path(path)
    temp_name: str | None = None
    try:
        # A stop signal raised between mkstemp's creating the file and its name being known
        # here left the file behind (1 of 50 stress runs): it waits until the name is held.
        with deferred_stop_signals():
            fd, temp_name = tempfile.mkstemp(
                prefix=f".{path.name[:40]}.", suffix=".tmp", dir=path.parent
            )
        if mode == "wb":
            handle: IO[Any] = os.fdopen(fd, "wb")
        else:
            handle = os.fdopen(fd, "w", encoding="utf-8", newline=newline)
        with handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(temp_name, 0o644)
        os.replace(temp_name, path)
    except BaseException:
        if temp_name is not None:
            with contextlib.suppress(OSError):
                os.unlink(temp_name)
        raise


def atomic_write_text(path: Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically (see :func:`atomic_open`)."""
    with atomic_open(path, "w") as handle:
        handle.write(text)


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_open`)."""
    with atomic_open(path, "wb") as handle:
        handle.write(data)
