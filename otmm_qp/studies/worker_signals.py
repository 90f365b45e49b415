"""Dask worker preload: the embedded cluster's workers leave stop signals to the driver.

Ctrl-C in a terminal sends SIGINT to the whole foreground process group, so every worker of
an embedded ``LocalCluster`` got it too and printed a KeyboardInterrupt traceback (64 lines
for 4 workers) while the driver was already stopping them cleanly. The driver alone handles
Ctrl-C; it closes the cluster, which stops the workers. Loaded in each worker process through
``distributed.worker.preload`` (module import, in the worker's main thread), it runs the one
worker set-up, :func:`otmm_qp.interrupt.worker_initialiser`.
"""

from __future__ import annotations

from typing import Any

from otmm_qp.interrupt import worker_initialiser

#: Dask starts its workers from a thread of the cluster, not the driver's main thread: the
#: parent-death signal would follow that thread, so it stays off (the cluster stops them).
worker_initialiser(die_with_parent=False)


def dask_setup(worker: Any) -> None:
    """Dask preload hook (the import above already did the work)."""
    worker_initialiser(die_with_parent=False)
