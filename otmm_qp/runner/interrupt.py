"""SIGINT and SIGTERM as one "stop" request that cannot be lost.

The handler raises KeyboardInterrupt, but Python drops an exception raised where it cannot
propagate (e.g. inside a fork or logging hook), so the request is also remembered and
:func:`check` re-raises it at the next safe point (after each run, after each figure).
"""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Iterator
from types import FrameType

_requested = False


def _request(signum: int, frame: FrameType | None) -> None:
    global _requested
    _requested = True
    raise KeyboardInterrupt


def requested() -> bool:
    """A stop was requested by SIGINT or SIGTERM."""
    return _requested


def check() -> None:
    """Raise KeyboardInterrupt if a stop was requested (and possibly swallowed)."""
    if _requested:
        raise KeyboardInterrupt


@contextlib.contextmanager
def handle_stop_signals() -> Iterator[None]:
    """Route SIGINT and SIGTERM to :func:`_request` inside the block."""
    global _requested
    _requested = False
    previous = {s: signal.signal(s, _request) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


@contextlib.contextmanager
def deferred_stop_signals() -> Iterator[None]:
    """Hold SIGINT/SIGTERM back while the block runs; act on them when it ends.

    For start-up code that must not be interrupted half-way (forking a process pool, starting a
    Dask cluster): KeyboardInterrupt raised inside ``ProcessPoolExecutor`` start-up or
    ``LocalCluster.__init__`` leaves threads and processes half made (a traceback, an
    ``atexit`` AssertionError). Inside the block a signal only records a stop request
    (:func:`requested`); when the block ends normally, the previous handlers are restored and
    a recorded request raises KeyboardInterrupt at that safe point. Outside the main thread
    the block runs unchanged.

    Raises:
        KeyboardInterrupt: A stop signal arrived during the block.
    """
    global _requested
    arrived: list[int] = []

    def record(signum: int, frame: FrameType | None) -> None:
        global _requested
        _requested = True
        arrived.append(signum)

    try:
        previous = {s: signal.signal(s, record) for s in (signal.SIGINT, signal.SIGTERM)}
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    if arrived:
        raise KeyboardInterrupt
