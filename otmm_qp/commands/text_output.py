"""Printing or writing a command's Markdown: ``--out FILE`` checked before any compute.

One place for what every analysis command does with its text, so ``--out DIR``, ``--out ''``,
a missing folder or an unwritable place (``/proc/x.md``) are one line each, exit 2.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from otmm_qp.exceptions import ConfigError


def out_file(text: str | None) -> Path | None:
    """The ``--out`` file, checked: not empty, not a folder, in an existing folder.

    Raises:
        ConfigError: ``--out``, naming what is wrong.
    """
    if text is None:
        return None
    if text == "" or "\x00" in text:
        raise ConfigError("--out", "must be a file name, e.g. --out verdict.md")
    path = Path(text)
    if text.endswith(("/", os.sep)) or path.is_dir():
        raise ConfigError("--out", f"{text!r:.60} is a folder; give a file name inside it")
    folder = path.parent
    if not folder.is_dir():
        raise ConfigError("--out", f"folder {str(folder)!r:.60} does not exist")
    if not os.access(folder, os.W_OK):
        raise ConfigError("--out", f"folder {str(folder)!r:.60} is not writable")
    return path


def emit(text: str, out: Path | None) -> None:
    """Print ``text``, or write it (and a final newline) atomically to ``out``.

    Raises:
        ConfigError: ``--out`` cannot be written (one line with the reason).
    """
    if out is None:
        try:
            print(text)
        except BrokenPipeError:  # e.g. `... | head`: the reader left
            sys.stderr.close()
        return
    from otmm_qp.paths import atomic_write_text

    try:
        atomic_write_text(out, text + "\n")
    except OSError as error:
        reason = error.strerror or type(error).__name__
        raise ConfigError("--out", f"cannot write {str(out)!r:.60}: {reason}") from None
