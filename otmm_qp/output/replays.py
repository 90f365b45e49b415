"""The replays a results folder holds: what the run report links (``RESULTS_DIR/replays``).

:mod:`otmm_qp.replay` writes each replay with a ``.json`` sidecar (title, kind, frames);
:func:`find_replays` reads the sidecars. It lives in ``output/`` (the results layout) so the
run report never imports the replay package, which imports ``output/``.
"""

from __future__ import annotations

import json
from pathlib import Path

#: Folder of a results directory holding the replays.
REPLAY_FOLDER = "replays"


def find_replays(results_dir: Path) -> list[tuple[str, Path]]:
    """``(title, path relative to results_dir)`` of every replay already written, by file name.

    Reads the ``.json`` sidecars in ``RESULTS_DIR/replays``; a sidecar whose file is missing
    or that is unreadable is ignored.
    """
    folder = Path(results_dir) / REPLAY_FOLDER
    if not folder.is_dir():
        return []
    found = []
    for sidecar in sorted(folder.glob("*.json")):
        try:
            description = json.loads(sidecar.read_text(encoding="utf-8"))
            title, name = str(description["title"]), str(description["file"])
        except (OSError, ValueError, KeyError, TypeError):
            continue
        target = folder / name
        if Path(name).name == name and target.is_file() and target.suffix in (".html", ".gif"):
            found.append((title, Path(REPLAY_FOLDER) / name))
    return found
