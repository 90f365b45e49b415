"""SIGINT and SIGTERM as one "stop" request that no library can lose: the one stop-signal path.

A leaf module (standard library only): backends import :func:`sigint_held` without the harness.

* :func:`handle_stop_signals` is the one place a stop signal becomes the program's interrupt:
  ``KeyboardInterrupt`` in the main thread, and a request remembered for :func:`check` (Python
  drops an exception raised where it cannot propagate, e.g. in a finaliser or a library's
  ``except BaseException``). The CLI enters it first thing, before its heavy imports; a study
  (:func:`otmm_qp.studies.execute.run_study`) enters it too, so the Python API gets the same
  path. Nested blocks share the outer one. A stop raised where Python drops it (a finaliser) is
  recorded silently and raised at the next safe point (after each study chunk, each run).
* Inside it, on POSIX systems with ``sigwaitinfo`` (Linux), SIGINT and SIGTERM are **blocked in
  every thread** (the main thread blocks them first, so every thread started later — Dask's,
  rich's, a pool's — inherits the mask) and **one watcher thread** receives them
  (``sigwaitinfo``) and hands them to the main thread (``_thread.interrupt_main``). No signal
  is ever delivered to a thread, so no C library's handler can take it: OSQP installs its own
  SIGINT handler for each solve and swallowed a Ctrl-C that arrived during its polishing (a
  window its status cannot report); Clarabel's and OSQP's calls now end normally and the
  interrupt is raised when they return. The main thread's waits poll (Dask's
  ``as_completed``: every 0.1 s; the figure pool: per drawing), so the interrupt is raised
  within that time.
* :func:`worker_initialiser` is the one set-up of a worker process (Dask worker, figure pool):
  the driver alone handles stop signals.
"""

from __future__ import annotations

import _thread
import contextlib
import functools
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from types import FrameType
from typing import Any, TypeVar

#: The stop signals.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
#: The watcher's own stop token: a real-time signal (queued, never merged with a user's stop
#: signal), sent to the watcher thread alone when the block closes.
_TOKEN: int | None = getattr(signal, "SIGRTMAX", None)
_PR_SET_PDEATHSIG = 1

_T = TypeVar("_T")
_requested = False
_depth = 0
_watching = False  # a watcher thread receives the stop signals (see handle_stop_signals)


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


class _Watcher:
    """The one thread that receives the stop signals while every other thread blocks them."""

    def __init__(self, token: int) -> None:
        self.closing = False
        self.token = token
        self.mask: set[int | signal.Signals] = set()  # the main thread's mask before
        self.thread = threading.Thread(target=self._run, name="otmm-qp stop signals", daemon=True)

    def _run(self) -> None:
        while True:
            info = signal.sigwaitinfo((*STOP_SIGNALS, self.token))
            if info.si_signo == self.token:
                if self.closing:
                    return
                continue  # someone else's real-time signal: not ours to act on
            global _requested
            _requested = True
            _thread.interrupt_main(signal.Signals(info.si_signo))  # run by its Python handler

    @classmethod
    def start(cls) -> _Watcher | None:
        """Block the stop signals in this (the main) thread and start the watcher.

        None where the platform has no ``sigwaitinfo`` (the signals are delivered as usual).
        """
        if not hasattr(signal, "sigwaitinfo") or _TOKEN is None:
            return None
        watcher = cls(_TOKEN)
        # blocked in this thread first: the watcher and every thread started later inherit it
        watcher.mask = signal.pthread_sigmask(signal.SIG_BLOCK, (*STOP_SIGNALS, watcher.token))
        watcher.thread.start()
        return watcher

    def stop(self) -> None:
        """Stop the watcher (a signal it takes first is still handed on), unblock the signals."""
        self.closing = True
        ident = self.thread.ident
        if ident is not None and self.thread.is_alive():
            signal.pthread_kill(ident, self.token)
        self.thread.join()
        signal.pthread_sigmask(signal.SIG_SETMASK, self.mask)  # pending ones are delivered now


def _quiet_stop(hook: Callable[[Any], object], unraisable: Any) -> None:
    """``sys.unraisablehook``: a stop raised where Python drops it is recorded, not printed.

    The handler's KeyboardInterrupt can land in a finaliser or a weakref callback ("Exception
    ignored in: <function WeakKeyDictionary…>" and a traceback, 1 of 50 stress runs); the
    request is recorded and :func:`check` raises it at the next safe point. Anything else goes
    to ``hook``.
    """
    if not (isinstance(unraisable.exc_value, KeyboardInterrupt) and _requested):
        hook(unraisable)


@contextlib.contextmanager
def handle_stop_signals(then_ignore: bool = False) -> Iterator[None]:
    """Turn SIGINT and SIGTERM into a stop request (KeyboardInterrupt) inside the block.

    The one stop-signal path (see the module's description): Python handlers raising
    KeyboardInterrupt, the signals blocked in every thread and received by one watcher
    thread. Outside the main thread, or nested in another such block, it changes nothing.

    Args:
        then_ignore: Ignore the stop signals after the block instead of restoring the previous
            handlers (the CLI's process: its outcome is decided, a late signal changes nothing).

    Raises:
        KeyboardInterrupt: A stop signal arrived (also one arriving while the block closes).
    """
    global _requested, _depth, _watching
    if threading.current_thread() is not threading.main_thread():
        # Another thread's block changes nothing, not even the nesting depth: counted here, it
        # made a main-thread block entered meanwhile believe it was nested (no handlers).
        yield
        return
    if _depth:
        _depth += 1
        try:
            yield
        finally:
            _depth -= 1
        return
    _requested = False
    previous = {s: signal.signal(s, _request) for s in STOP_SIGNALS}
    hook = sys.unraisablehook
    sys.unraisablehook = functools.partial(_quiet_stop, hook)
    watcher = _Watcher.start()
    _watching = watcher is not None
    _depth = 1
    closing: list[int] = []
    try:
        yield
    finally:
        # A signal handed on while closing is recorded, not raised half-way through the close.
        for s in STOP_SIGNALS:
            signal.signal(s, lambda signum, frame: closing.append(signum))
        _watching = False
        if watcher is not None:
            watcher.stop()
        for signum, handler in previous.items():
            signal.signal(signum, signal.SIG_IGN if then_ignore else handler)
        sys.unraisablehook = hook
        _depth = 0
    if closing:
        _requested = True
        raise KeyboardInterrupt


@contextlib.contextmanager
def stop_signals_unblocked() -> Iterator[None]:
    """Start a child process inside this block: it gets the stop signals unblocked.

    A child inherits the signal mask of the thread that starts it; under
    :func:`handle_stop_signals` that mask blocks SIGINT and SIGTERM, and a browser started so
    ignored ``terminate()``. Inside the block the stop signals are deferred
    (:func:`deferred_stop_signals`: a start is never cut half-way) and unblocked in this thread.

    Raises:
        KeyboardInterrupt: A stop signal arrived during the block.
    """
    with deferred_stop_signals():
        unblocked = (*STOP_SIGNALS, _TOKEN) if _TOKEN is not None else STOP_SIGNALS
        previous = (
            signal.pthread_sigmask(signal.SIG_UNBLOCK, unblocked)
            if hasattr(signal, "pthread_sigmask")
            else None
        )
        try:
            yield
        finally:
            if previous is not None:
                signal.pthread_sigmask(signal.SIG_SETMASK, previous)


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
    Python. Every call into native solvers goes through this block (the QP sessions', the peers'
    and the offline reference's OSQP and Clarabel solves)::

        with sigint_held() as held:
            result = solver.solve(raise_error=False)
            held.swallowed = result.info.status_val == OSQP_SIGINT

    Under :func:`handle_stop_signals` (the CLI, a study) every thread blocks SIGINT already and
    the one watcher thread receives it: no library handler runs, the block costs two
    ``pthread_sigmask`` calls (about a microsecond). Without it (a library user's own code),
    SIGINT is blocked for the calling thread (``pthread_sigmask``: a pending SIGINT goes to
    Python's handler when the block ends); a SIGINT the kernel delivers to another thread still
    reaches the library's handler, so the caller sets ``swallowed`` from the library's status
    and the signal is raised again when the block ends (one window stays open there: a SIGINT
    OSQP's handler takes during polishing, after its last test of its flag, is lost).

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
        _give_back_sigint()


def solve_held(solve: Callable[[], _T], swallowed: Callable[[_T], bool]) -> _T:
    """``solve()`` inside :func:`sigint_held`; solved again if the library caught an ignored SIGINT.

    ``swallowed(result)`` says the library's own handler caught SIGINT (OSQP's status
    ``OSQP_SIGINT``): the signal is given back (KeyboardInterrupt where it is handled). In a
    process that ignores SIGINT — a worker, whose threads started before its initialiser ran can
    still take one while OSQP's handler is installed — the interrupted solve is not a result:
    it is solved again, so Ctrl-C never changes a worker's numbers.
    """
    while True:
        with sigint_held() as held:
            result = solve()
            held.swallowed = swallowed(result)
        if not held.swallowed:
            return result


def _give_back_sigint() -> None:
    """Hand a SIGINT a library caught itself to Python's handler."""
    if _depth and threading.current_thread() is threading.main_thread():
        global _requested
        _requested = True  # the signal itself would stay blocked: the request, directly
        raise KeyboardInterrupt
    signal.raise_signal(signal.SIGINT)


@contextlib.contextmanager
def deferred_stop_signals(spawning: bool = False) -> Iterator[None]:
    """Hold SIGINT/SIGTERM back while the block runs; act on them when it ends.

    For start-up code that must not be interrupted half-way (forking a process pool, starting a
    Dask cluster): KeyboardInterrupt raised inside ``ProcessPoolExecutor`` start-up or
    ``LocalCluster.__init__`` leaves threads and processes half made (a traceback, an
    ``atexit`` AssertionError). Inside the block a signal only records a stop request
    (:func:`requested`); when the block ends normally, the previous handlers are restored and
    a recorded request raises KeyboardInterrupt at that safe point. Outside the main thread
    the block runs unchanged.

    Args:
        spawning: The block starts processes (``exec``: Dask's workers) that must ignore
            Ctrl-C from their first instruction. Under :func:`handle_stop_signals` SIGINT is
            then *ignored* in the block, which a new program inherits (a handler is not: Ctrl-C
            in the terminal reached a worker still importing, a KeyboardInterrupt traceback per
            worker); the driver still gets it, since a signal its every thread blocks is never
            discarded (Linux) and the watcher takes it.

    Raises:
        KeyboardInterrupt: A stop signal arrived during the block.
    """
    global _requested
    arrived: list[int] = []

    def record(signum: int, frame: FrameType | None) -> None:
        global _requested
        _requested = True
        arrived.append(signum)

    ignore = spawning and _watching
    try:
        previous = {
            s: signal.signal(s, signal.SIG_IGN if ignore and s == signal.SIGINT else record)
            for s in STOP_SIGNALS
        }
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    if arrived or (ignore and _requested):  # the watcher records an ignored SIGINT
        raise KeyboardInterrupt


def worker_initialiser(die_with_parent: bool = True) -> None:
    """Set up a worker process (Dask worker, figure pool): the driver alone handles stop signals.

    Ctrl-C in a terminal sends SIGINT to the whole process group; the driver stops its workers,
    so a worker ignores SIGINT and keeps it blocked in every thread (no library's own handler —
    OSQP's — takes it and ends a solve as "interrupted"). SIGTERM is the default (the driver and
    Dask's nanny stop workers with it) and unblocked (a process started under
    :func:`handle_stop_signals` inherits the blocked mask). ``die_with_parent``: SIGTERM when the
    thread that started the process exits (Linux ``PR_SET_PDEATHSIG``), so a killed driver
    leaves no worker behind; Dask's workers, started from a thread of the cluster, leave it off.
    Runs in the worker's main thread; elsewhere it changes nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        return
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGTERM})
    if die_with_parent:
        import ctypes
        import ctypes.util

        with contextlib.suppress(OSError, AttributeError):
            libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
            if os.getppid() == 1:  # the parent died before prctl took effect
                os._exit(1)
