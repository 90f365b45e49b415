"""SIGINT and SIGTERM as one "stop" request that cannot be lost.

The handler raises KeyboardInterrupt, but Python drops an exception raised where it cannot
propagate (e.g. inside a fork or logging hook), so the request is also remembered and
:func:`check` re-raises it at the next safe point (after each run, after each figure).

A C library that installs its own SIGINT handler while it computes (OSQP's interrupt listener:
it swallows Ctrl-C and returns status ``interrupted``) is called inside :func:`sigint_held`,
so the signal waits for Python's handler instead.
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


class HeldSigint:
    """What :func:`sigint_held` yields: set :attr:`swallowed` when the library says it was hit.

    Attributes:
        swallowed: The native code reported that it caught SIGINT itself (OSQP's status
            ``OSQP_SIGINT``): the signal is given back to Python's handler when the block ends.
    """

    swallowed: bool = False


@contextlib.contextmanager
def sigint_held() -> Iterator[HeldSigint]:
    """Keep SIGINT from native code that installs its own handler; Python handles it after.

    OSQP installs its own SIGINT handler for each ``solve`` (and restores the previous one
    after): a Ctrl-C during a solve ended that solve as ``interrupted`` and never reached
    Python, so a study went on and stored the task's offline reference as ``failed``. Inside
    the block SIGINT is blocked for the calling thread (``pthread_sigmask``: a pending SIGINT
    goes to Python's handler when the block ends); a SIGINT the kernel delivers to another
    thread still reaches the library's handler, so the caller sets ``swallowed`` from the
    library's status and the signal is raised again (``signal.raise_signal``) when the block
    ends. One window stays open: OSQP tests its flag once per ADMM iteration, so a SIGINT its
    handler takes after the last test (during polishing, when ``polishing`` is on) ends neither
    the solve nor reaches Python — the flag is OSQP's own, no caller can read it (measured: 1
    of 12 probes with polishing on a 400-variable problem; 0 of 20 without). Cost: two
    ``pthread_sigmask`` calls (about a microsecond). Every call into such a
    library goes through it: the QP sessions' and the offline reference's OSQP solves::

        with sigint_held() as held:
            result = solver.solve(raise_error=False)
            held.swallowed = result.info.status_val == OSQP_SIGINT

    Raises:
        KeyboardInterrupt: When the block ends, if SIGINT arrived during it (from Python's
            handler, or :func:`_request` under :func:`handle_stop_signals`).
    """
    held = HeldSigint()
    masks = hasattr(signal, "pthread_sigmask")  # POSIX signal masks (not on Windows)
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT}) if masks else None
    try:
        yield held
    finally:
        if previous is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, previous)
    if held.swallowed:
        signal.raise_signal(signal.SIGINT)


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
