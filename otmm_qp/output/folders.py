"""Folder kinds and locks: every folder the CLI writes says what wrote it, and one writer at a time.

The four kinds are ``run`` (``otmm-qp run``: ``summary.csv``, experiment folders, reports),
``study`` (``otmm-qp study``: ``study.json``, ``episodes/``, the study report), ``bench``
(``otmm-qp bench``: ``bench.json``, ``bench.md``) and ``replay`` (``RUN_FOLDER/replays``,
written by ``otmm-qp replay`` or ``run --replay``). :func:`claim_folder`:

1. refuses an empty or NUL-holding path and a folder that is the current directory, one of
   its parents, or the default ``results/`` itself (a name ``.``/``..`` would land there);
2. creates the folder and takes an exclusive, non-blocking ``flock`` on ``.otmm-qp.lock``:
   a second writer of any kind fails at once instead of writing alongside;
3. reads the kind (the ``.otmm-qp-kind`` marker, or for folders written before markers
   existed, the files each kind writes); another kind is refused, or with ``force`` every file
   and folder that kind writes is removed first;
4. writes the marker and yields the folder, the lock held until the ``with`` block ends.

Files a user put in the folder are never removed: removal takes only the names in
:data:`KIND_FILES`, never follows a symlink, and removes a folder only when every file in it
has a suffix otmm-qp writes.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Literal

from otmm_qp.exceptions import OutputPathError

Kind = Literal["run", "study", "bench", "replay"]
KINDS: tuple[Kind, ...] = ("run", "study", "bench", "replay")
LOCK_NAME = ".otmm-qp.lock"
KIND_NAME = ".otmm-qp-kind"
#: Top-level names each kind writes (files, or folders of files it wrote).
KIND_FILES: dict[str, tuple[str, ...]] = {
    "run": ("summary.csv", "summary.md", "claims.md", "report.html", "report.md", "replays"),
    "study": (
        "study.json",
        "episodes",
        "timeseries",
        "figures",
        "study_report.html",
        "study_report.md",
        "certificates",
    ),
    "bench": ("bench.json", "bench.md"),
    "replay": (),
}
#: Files whose presence alone shows a folder's kind (folders written before the marker).
_SIGNATURES: dict[str, tuple[str, ...]] = {
    "run": ("summary.csv", "summary.md", "report.html"),
    "study": ("study.json", "episodes"),
    "bench": ("bench.json",),
}
#: Suffixes of the files otmm-qp writes inside the folders it creates.
WRITTEN_SUFFIXES = (".csv", ".png", ".html", ".md", ".gif", ".json", ".parquet", ".tmp")


def check_out_argument(text: str) -> Path:
    """The ``--out`` string as a path; '' and NUL refused (an empty path is the cwd).

    Raises:
        OutputPathError: ``text`` is empty or holds a NUL character.
    """
    if text == "":
        raise OutputPathError(text, "must not be empty; give a folder name, e.g. --out results/x")
    if "\x00" in text:
        raise OutputPathError(text, "must not contain a NUL character")
    return Path(text)


def _check_not_shared(folder: Path) -> None:
    """Refuse the cwd, its parents and ``./results`` itself (where ``.``/``..`` names land)."""
    resolved = Path(os.path.realpath(folder))
    cwd = Path(os.path.realpath(Path.cwd()))
    if resolved == cwd or resolved in cwd.parents:
        raise OutputPathError(
            str(folder), "is the current directory or one of its parents; choose a subfolder"
        )
    if resolved == cwd / "results":
        raise OutputPathError(
            str(folder), "is the 'results' folder itself; choose a subfolder, e.g. results/x"
        )


def folder_kind(folder: Path) -> str | None:
    """The kind of ``folder`` (its marker, else the files it holds), or None for a fresh folder.

    A marker that is unreadable, a symlink or names no known kind counts as absent.
    """
    marker = folder / KIND_NAME
    if marker.is_file() and not marker.is_symlink():
        try:
            kind = json.loads(marker.read_text(encoding="utf-8")).get("kind")
        except (OSError, ValueError, AttributeError):
            kind = None
        if kind in KINDS:
            return str(kind)
    for kind, names in _SIGNATURES.items():
        if any((folder / name).exists() or (folder / name).is_symlink() for name in names):
            return kind
    return None


def _written_by_otmm(path: Path) -> bool:
    """A folder holding only folders and files with suffixes otmm-qp writes (no symlinks)."""
    return all(
        not p.is_symlink()
        and (p.is_dir() or p.suffix in WRITTEN_SUFFIXES or p.name in (LOCK_NAME, KIND_NAME))
        for p in path.rglob("*")
    )


def remove_kind_files(folder: Path, kind: str) -> None:
    """Remove what ``kind`` wrote in ``folder`` (see :data:`KIND_FILES`); symlinks are unlinked.

    Run folders also hold one folder per experiment: any folder of otmm-qp files is removed.
    """
    names = set(KIND_FILES.get(kind, ()))
    for entry in folder.iterdir():
        if entry.name in (LOCK_NAME, KIND_NAME):
            continue
        if entry.is_symlink():
            if entry.name in names:
                entry.unlink()
            continue
        if entry.is_file() and entry.name in names:
            entry.unlink()
        elif entry.is_dir() and (entry.name in names or kind == "run") and _written_by_otmm(entry):
            shutil.rmtree(entry)


def _write_marker(folder: Path, kind: str) -> None:
    from otmm_qp.paths import atomic_write_text

    marker = folder / KIND_NAME
    if marker.is_symlink():
        marker.unlink()
    atomic_write_text(marker, json.dumps({"kind": kind}) + "\n")


def _open_lock(folder: Path) -> int:
    shown = str(folder)
    try:
        if folder.exists() and not folder.is_dir():
            raise OutputPathError(shown, "exists and is not a directory")
        folder.mkdir(parents=True, exist_ok=True)
        lock_path = folder / LOCK_NAME
        if lock_path.is_symlink():
            lock_path.unlink()
        return os.open(lock_path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)
    except OSError as error:
        reason = error.strerror or str(error)
        if error.errno == errno.ENAMETOOLONG:
            reason = "a path component is too long"
        raise OutputPathError(shown, f"cannot create a results folder there: {reason}") from None


@contextlib.contextmanager
def lock_folder(folder: Path) -> Iterator[Path]:
    """Create ``folder`` and hold its exclusive lock for the block (no kind check).

    Raises:
        OutputPathError: An unusable path, or the folder is held by another otmm-qp command.
    """
    shown = str(folder)
    if shown == "" or "\x00" in shown:
        check_out_argument(shown)
    lock = _open_lock(folder)
    try:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise OutputPathError(
                shown,
                "another otmm-qp command is writing this folder; wait or choose another --out",
            ) from None
        yield folder
    finally:
        os.close(lock)  # releases the flock; the file stays (ignored by every reader)


@contextlib.contextmanager
def claim_folder(folder: Path, kind: Kind, force: bool = False) -> Iterator[Path]:
    """Create, lock and mark ``folder`` for one writer of ``kind`` (see the module docstring).

    Args:
        folder: The folder to write.
        kind: What will write it.
        force: Replace a folder of another kind (its files are removed first).

    Yields:
        ``folder``, locked until the block ends.

    Raises:
        OutputPathError: An unusable path, a folder held by another otmm-qp command, or a
            folder of another kind while ``force`` is False.
    """
    _check_not_shared(folder)
    with lock_folder(folder):
        found = folder_kind(folder)
        if found is not None and found != kind:
            if not force:
                raise OutputPathError(
                    str(folder),
                    f"is a {found} folder; otmm-qp {kind} writes only a new or a {kind} folder "
                    "(pass --force to replace its contents, or choose another --out)",
                )
            remove_kind_files(folder, found)
        if found != kind:  # a folder already of this kind keeps its files untouched here
            try:
                _write_marker(folder, kind)
            except OSError as error:
                raise OutputPathError(
                    str(folder), f"cannot write there: {error.strerror}"
                ) from None
        yield folder
