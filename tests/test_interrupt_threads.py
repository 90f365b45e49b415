"""``handle_stop_signals`` entered from another thread never disarms the main thread's block."""

from __future__ import annotations

import os
import signal
import threading
import time

import pytest

from otmm_qp import interrupt


def test_a_block_in_another_thread_leaves_the_main_threads_block_armed() -> None:
    inside = threading.Event()
    release = threading.Event()

    def other() -> None:
        with interrupt.handle_stop_signals():
            inside.set()
            release.wait(10)

    thread = threading.Thread(target=other)
    thread.start()
    try:
        assert inside.wait(10)
        before = signal.getsignal(signal.SIGTERM)
        with pytest.raises(KeyboardInterrupt):  # noqa: PT012 - the block is the subject
            with interrupt.handle_stop_signals():
                # armed: the main thread's handler is the stop request, not the previous one
                assert signal.getsignal(signal.SIGTERM) is not before
                os.kill(os.getpid(), signal.SIGTERM)  # process-directed, as a user sends it
                deadline = time.monotonic() + 10  # the watcher thread hands it on
                while not interrupt.requested() and time.monotonic() < deadline:
                    time.sleep(0.01)
                interrupt.check()
        assert interrupt.requested()
    finally:
        release.set()
        thread.join(10)
    assert signal.getsignal(signal.SIGTERM) is before
