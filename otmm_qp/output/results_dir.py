"""Claim a results folder before any compute: a writable directory, locked, not mixed.

A folder that already holds results is refused unless ``force`` (then the files otmm-qp wrote
there are removed first, so a report never shows an older run's figures); a lock file held
with ``flock`` stops a second, concurrent run writing the same folder.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import shutil
from collections.abc import Iterator
from pathlib import Path

from otmm_qp.exceptions import OutputPathError

LOCK_NAME = ".otmm-qp.lock"
#: Files of a results folder's top level that otmm-qp writes.
RESULT_FILES = ("summary.csv", "summary.md", "claims.md", "report.html", "report.md")
#: Suffixes of the files otmm-qp writes in experiment folders.
RESULT_SUFFIXES = (".csv", ".png", ".html", ".md", ".gif", ".json")


def check_out_argument(text: str) -> Path:
    """The ``--out`` string as a path; '' and NUL refused (an empty path is the cwd)."""
    if text == "":
        raise OutputPathError(text, "must not be empty; give a folder name, e.g. --out results/x")
    if "\x00" in text:
        raise OutputPathError(text, "must not contain a NUL character")
    return Path(text)


def _holds_results(folder: Path) -> bool:
    """An earlier run wrote here (its summary or report); other files do not count."""
    return any((folder / name).exists() or (folder / name).is_symlink() for name in RESULT_FILES)


def _remove_old_results(folder: Path) -> None:
    """Remove what an earlier otmm-qp run wrote (other files are left alone)."""
    for entry in folder.iterdir():
        if entry.is_symlink():
            continue
        if entry.is_file() and entry.name in RESULT_FILES:
            entry.unlink()
        elif entry.is_dir() and all(
            p.is_dir() or (p.is_file() and p.suffix in RESULT_SUFFIXES) for p in entry.rglob("*")
        ):
            shutil.rmtree(entry)


@contextlib.contextmanager
def claim_results_dir(out_dir: Path, force: bool = False) -> Iterator[Path]:
    """Create and lock ``out_dir`` for one run.

    Raises:
        OutputPathError: Not a directory, not creatable or writable, held by another run, or
            holding results of an earlier run while ``force`` is False.
    """
    shown = str(out_dir)
    if shown == "" or "\x00" in shown:
        check_out_argument(shown)
    try:
        if out_dir.exists() and not out_dir.is_dir():
            raise OutputPathError(shown, "exists and is not a directory")
        out_dir.mkdir(parents=True, exist_ok=True)
        lock = os.open(out_dir / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as error:
        reason = error.strerror or str(error)
        if error.errno == errno.ENAMETOOLONG:
            reason = "a path component is too long"
        raise OutputPathError(shown, f"cannot create a results folder there: {reason}") from None
    try:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise OutputPathError(
                shown, "another otmm-qp run is writing this folder; wait or choose another --out"
            ) from None
        if _holds_results(out_dir):
            if not force:
                raise OutputPathError(
                    shown,
                    "already holds results of an earlier run; pass --force to replace them "
                    "or choose another --out",
                )
            _remove_old_results(out_dir)
        yield out_dir
    finally:
        os.close(lock)  # releases the flock; the file stays (harmless, ignored by report)
