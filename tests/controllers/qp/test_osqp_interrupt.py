"""Ctrl-C during an OSQP solve reaches Python (OSQP's own SIGINT handler no longer eats it)."""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap

import pytest

PROBE = textwrap.dedent(
    """
    import os, signal, sys, threading, time
    import numpy as np
    from otmm_qp import interrupt
    from otmm_qp_controllers.qp.solvers.osqp_session import OsqpSession
    from otmm_qp_controllers.qp.solvers.problem import QpProblem

    n, m = 400, 300  # a solve takes ~0.1-0.4 s: the signal lands inside one
    rng = np.random.default_rng(0)
    A = rng.standard_normal((n, n))
    problem = QpProblem(A @ A.T + np.eye(n), rng.standard_normal(n), -np.ones(n), np.ones(n),
                        rng.standard_normal((m, n)), -np.ones(m), np.ones(m))
    session = OsqpSession()
    session.setup(problem)
    # OSQP tests its interrupt flag once per ADMM iteration; a SIGINT its handler takes during
    # the polish after the last test is lost inside OSQP (a window no caller can close: the
    # flag is OSQP's own). Without polishing that window is microseconds, so this checks the
    # mechanism itself: the status OSQP reports is turned back into KeyboardInterrupt.
    session._solver.update_settings(polishing=False)
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


REFERENCE = textwrap.dedent(
    """
    import os, signal, sys, threading, time
    import numpy as np
    import otmm_qp.reference.sqp as sqp
    # Every OSQP solve of the reference made long, so the signal lands inside one.
    sqp.OSQP_SETTINGS.update(eps_abs=1e-12, eps_rel=1e-12, max_iter=200000)
    from otmm_qp.reference import ReferenceSettings, solve_reference
    from otmm_qp.robots.pinocchio_arm import PinocchioArm
    from otmm_qp import interrupt
    from otmm_qp.trajectories.line import QuinticLineTrajectory

    robot = PinocchioArm(name="panda", task="position")
    q0 = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
    start = robot.forward(robot.configuration(q0))
    line = QuinticLineTrajectory(start, (start + np.array([0.5, 0.3, 0.2])).tolist(), 3.0)
    threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
    try:
        with interrupt.handle_stop_signals():
            result, _ = solve_reference(
                robot, line, q0, 0.005, 4.0, ReferenceSettings(time_budget=20.0)
            )
    except KeyboardInterrupt:
        print("interrupted", flush=True)
        sys.exit(130)
    print(f"not interrupted: reference {result.status}", flush=True)
    """
)


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_sigint_during_the_offline_reference_is_not_a_failed_reference() -> None:
    """Before: OSQP ate the Ctrl-C, the solve ended ``failed`` and the study went on."""
    done = subprocess.run(
        [sys.executable, "-c", REFERENCE], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 130, done.stdout + done.stderr
    assert done.stdout.strip().endswith("interrupted") and "not interrupted" not in done.stdout


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_sigint_during_an_osqp_solve_raises_keyboard_interrupt() -> None:
    done = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=60)
    assert done.returncode == 130, done.stdout + done.stderr
    assert "interrupted after" in done.stdout


def test_sigint_held_gives_a_swallowed_signal_back() -> None:
    """A library that caught SIGINT itself (``swallowed``): KeyboardInterrupt at the end."""
    from otmm_qp.interrupt import sigint_held

    # The signal given back goes to the process's SIGINT handler: make it Python's default here,
    # whatever the test runner installed (pytest-xdist's workers ignore SIGINT).
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        ran = []
        with pytest.raises(KeyboardInterrupt), sigint_held() as held:
            held.swallowed = True
            ran.append(1)
        assert ran == [1]
        with sigint_held():  # nothing arrived: nothing raised
            ran.append(2)
        assert ran == [1, 2]
    finally:
        signal.signal(signal.SIGINT, previous)


@pytest.mark.parametrize("handled", [True, False], ids=["driver", "worker"])
def test_a_swallowed_sigint_interrupts_a_driver_and_is_solved_again_in_a_worker(
    handled: bool,
) -> None:
    """A library that caught SIGINT itself: KeyboardInterrupt where SIGINT is handled; where it
    is ignored (a worker), the interrupted solve is no result and is solved again."""
    from otmm_qp.interrupt import solve_held

    statuses = iter(["interrupted", "solved"])
    calls: list[str] = []

    def solve() -> str:
        calls.append(next(statuses))
        return calls[-1]

    handler = signal.default_int_handler if handled else signal.SIG_IGN
    previous = signal.signal(signal.SIGINT, handler)
    try:
        if handled:
            with pytest.raises(KeyboardInterrupt):
                solve_held(solve, lambda status: status == "interrupted")
            assert calls == ["interrupted"]
        else:
            assert solve_held(solve, lambda status: status == "interrupted") == "solved"
            assert calls == ["interrupted", "solved"]
    finally:
        signal.signal(signal.SIGINT, previous)
