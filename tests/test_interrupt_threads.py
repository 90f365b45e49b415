"""``handle_stop_signals`` entered from another thread never disarms the main thread's block.

Run in a child interpreter: the scenario needs the process's main thread (pytest-xdist may run
tests elsewhere) and sends the process a real SIGTERM.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

SCENARIO = textwrap.dedent(
    """
    import os, signal, threading, time
    from otmm_qp import interrupt

    inside, release = threading.Event(), threading.Event()

    def other():
        with interrupt.handle_stop_signals():
            inside.set()
            release.wait(10)

    thread = threading.Thread(target=other)
    thread.start()
    assert inside.wait(10)
    before = signal.getsignal(signal.SIGTERM)
    stopped = False
    try:
        with interrupt.handle_stop_signals():
            armed = signal.getsignal(signal.SIGTERM) is not before
            os.kill(os.getpid(), signal.SIGTERM)  # process-directed, as a user sends it
            deadline = time.monotonic() + 10  # the watcher thread hands it on
            while not interrupt.requested() and time.monotonic() < deadline:
                time.sleep(0.01)
            interrupt.check()
    except KeyboardInterrupt:
        stopped = True
    finally:
        release.set()
        thread.join(10)
    restored = signal.getsignal(signal.SIGTERM) is before
    print(f"armed={armed} stopped={stopped} restored={restored}")
    """
)


def test_a_block_in_another_thread_leaves_the_main_threads_block_armed() -> None:
    done = subprocess.run(
        [sys.executable, "-c", SCENARIO], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.stdout.strip() == "armed=True stopped=True restored=True", done.stderr
    assert done.returncode == 0, done.stderr
