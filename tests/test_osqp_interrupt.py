"""Ctrl-C during an OSQP solve reaches Python (OSQP's own SIGINT handler no longer eats it)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

PROBE = textwrap.dedent(
    """
    import os, signal, sys, threading, time
    import numpy as np
    from otmm_qp.runner import interrupt
    from otmm_qp_controllers.qp.solvers.osqp_session import OsqpSession
    from otmm_qp_controllers.qp.solvers.problem import QpProblem

    n, m = 400, 300  # a solve takes ~0.1-0.4 s: the signal lands inside one
    rng = np.random.default_rng(0)
    A = rng.standard_normal((n, n))
    problem = QpProblem(A @ A.T + np.eye(n), rng.standard_normal(n), -np.ones(n), np.ones(n),
                        rng.standard_normal((m, n)), -np.ones(m), np.ones(m))
    session = OsqpSession()
    session.setup(problem)
    threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
    start, solves = time.perf_counter(), 0
    try:
        with interrupt.handle_stop_signals():
            while time.perf_counter() - start < 6.0:
                problem.q[:] = rng.standard_normal(n)
                session.update(problem)
                session.solve()
                solves += 1
    except KeyboardInterrupt:
        print(f"interrupted after {solves} solves", flush=True)
        sys.exit(130)
    print(f"not interrupted: {solves} solves", flush=True)
    """
)


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_sigint_during_an_osqp_solve_raises_keyboard_interrupt() -> None:
    done = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=60)
    assert done.returncode == 130, done.stdout + done.stderr
    assert "interrupted after" in done.stdout


def test_sigint_held_gives_a_swallowed_signal_back() -> None:
    """A library that caught SIGINT itself (``swallowed``): KeyboardInterrupt at the end."""
    from otmm_qp.runner.interrupt import sigint_held

    ran = []
    with pytest.raises(KeyboardInterrupt), sigint_held() as held:
        held.swallowed = True
        ran.append(1)
    assert ran == [1]
    with sigint_held():  # nothing arrived: nothing raised
        ran.append(2)
    assert ran == [1, 2]
