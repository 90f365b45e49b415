"""Claim a results folder before any compute: a writable directory, locked, not mixed.

A folder that already holds results is refused unless ``force`` (then the files otmm-qp wrote
there are removed first, so a report never shows an older run's figures); a lock file held
with ``flock`` stops a second, concurrent run writing the same folder.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path

from otmm_qp.exceptions import OutputPathError
from otmm_qp.output.folders import (
    LOCK_NAME,
    check_out_argument,
    claim_folder,
    remove_kind_files,
)
from otmm_qp.output.results import CLAIMS_MD, REPORT_HTML, REPORT_MD, SUMMARY_CSV, SUMMARY_MD

__all__ = ["LOCK_NAME", "RESULT_FILES", "check_out_argument", "claim_results_dir"]

#: Files of a results folder's top level that otmm-qp writes.
RESULT_FILES = (SUMMARY_CSV, SUMMARY_MD, CLAIMS_MD, REPORT_HTML, REPORT_MD)


def _holds_results(folder: Path) -> bool:
    """An earlier run wrote here (its summary or report); other files do not count."""
    return any((folder / name).exists() or (folder / name).is_symlink() for name in RESULT_FILES)


@contextlib.contextmanager
def claim_results_dir(out_dir: Path, force: bool = False) -> Iterator[Path]:
    """Create, lock and mark ``out_dir`` as a run folder (see ``folders.claim_folder``).

    Raises:
        OutputPathError: Not a directory, not creatable or writable, held by another otmm-qp
            command, a folder of another kind, or holding results of an earlier run, while
            ``force`` is False.
    """
    with claim_folder(out_dir, "run", force) as folder:
        if _holds_results(folder):
            if not force:
                raise OutputPathError(
                    str(out_dir),
                    "already holds results of an earlier run; pass --force to replace them "
                    "or choose another --out",
                )
            remove_kind_files(folder, "run")
        yield folder
