"""One BLAS thread per process for otmm-qp's command-line processes, unless the user says otherwise.

The matrices of a control step are tiny (an arm Jacobian is at most 6 × 7), so a multithreaded
BLAS only adds thread wake-ups and spinning; with one Dask worker per core it also
oversubscribes the cores (measured: 2 workers gave 1.44 × the serial study throughput with
OpenBLAS's default threads, 1.71 × with one thread each). BLAS reads these variables once, when
it loads, so :func:`prefer_single_threaded_blas` must run before NumPy is first imported; a
value the user has set is kept.
"""

from __future__ import annotations

import os

#: The thread-count variables of OpenBLAS, OpenMP-based BLAS builds and MKL.
THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def prefer_single_threaded_blas() -> None:
    """Default each of :data:`THREAD_VARIABLES` to ``1`` (existing values are kept)."""
    for name in THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
