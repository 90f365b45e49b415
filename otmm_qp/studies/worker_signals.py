"""Dask worker preload: the embedded cluster's workers ignore SIGINT.

Ctrl-C in a terminal sends SIGINT to the whole foreground process group, so every worker of
an embedded ``LocalCluster`` got it too and printed a KeyboardInterrupt traceback (64 lines
for 4 workers) while the driver was already stopping them cleanly. The driver alone handles
Ctrl-C; it closes the cluster, which stops the workers. Loaded in each worker process through
``distributed.worker.preload`` (module import, in the worker's main thread).
"""

from __future__ import annotations

import contextlib
import signal
from typing import Any


def _ignore_sigint() -> None:
    with contextlib.suppress(ValueError):  # only possible in the main thread
        signal.signal(signal.SIGINT, signal.SIG_IGN)


_ignore_sigint()


def dask_setup(worker: Any) -> None:
    """Dask preload hook (the import above already did the work)."""
    _ignore_sigint()
