"""The closed simulation loop: state → command → filters → backend → Euler step."""

from __future__ import annotations

import math
import time

import numpy as np

from otmm_qp.controller import Controller
from otmm_qp.exceptions import InfeasibleProblem, OtmmError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.simulation.loop_modes import LoopMode, commanded_velocity
from otmm_qp.simulation.run_result import RunResult
from otmm_qp.state import KinematicState
from otmm_qp.trajectories.trajectory import Trajectory


def task_position(x: FloatArray) -> FloatArray:
    """Position part of a task value: the point itself, or the translation of a 4×4 pose."""
    return x[:3, 3] if x.ndim == 2 else x


def simulate(
    robot: Robot,
    controller: Controller,
    trajectory: Trajectory,
    q0: FloatArray,
    dt: float,
    duration: float,
    loop_mode: LoopMode = "clik",
    clik_gain: float = 10.0,
    task_weight: FloatArray | None = None,
    experiment: str = "",
) -> RunResult:
    r"""Run ``controller`` on ``robot`` along ``trajectory`` with explicit Euler integration.

    .. math:: q_{k+1} = q_k \oplus \dot q_k\,dt,\qquad \dot q_{-1} = 0

    Args:
        robot: The arm.
        controller: Filters + backend.
        trajectory: Desired motion.
        q0: Start configuration, shape ``(nq,)`` (already checked against limits).
        dt: Control period [s].
        duration: Simulated time [s]; ``round(duration/dt)`` steps are taken.
        loop_mode: How ``ẋ_c`` is formed (see :mod:`otmm_qp.simulation.loop_modes`).
        clik_gain: CLIK gain K [1/s].
        task_weight: Diagonal task weight ``W``, shape ``(n,)``.
        experiment: Experiment name recorded in the result.

    Returns:
        The time series. A typed error inside the loop (e.g. an infeasible QP with the
        ``raise`` policy) stops the run early; the steps done so far are kept and
        ``error_message`` says why.
    """
    steps = max(1, int(round(duration / dt)))
    nv = robot.nv
    n = robot.task_dim
    controller.bind(robot, dt)
    t = np.arange(steps) * dt
    q_log = np.zeros((steps, nv))
    qdot_log = np.zeros((steps, nv))
    error_log = np.zeros((steps, n))
    sigma_log = np.zeros(steps)
    p_log = np.zeros(steps)
    active_log = np.zeros(steps, dtype=bool)
    removed_log = np.zeros(steps)
    damping_log = np.full(steps, np.nan)
    scale_log = np.ones(steps)
    weak_log = np.zeros(steps)
    status_log = np.empty(steps, dtype=object)
    time_log = np.zeros(steps)
    positions: list[FloatArray] = []
    desired: list[FloatArray] = []

    q = np.array(q0, dtype=float)
    qdot_prev = np.zeros(nv)
    error_message: str | None = None
    done = 0
    for k in range(steps):
        tk = float(t[k])
        xd, xd_dot = trajectory.sample(tk)
        tic = time.perf_counter()
        state = KinematicState.compute(robot, q, task_weight)
        tracking_error = robot.task_error(xd, state.x)
        command = commanded_velocity(
            loop_mode, robot, trajectory, tk, dt, state.x, tracking_error, xd_dot, clik_gain
        )
        try:
            output = controller.step(state, command, qdot_prev)
        except InfeasibleProblem as error:
            error_message = str(InfeasibleProblem(k, error.detail))
            break
        except OtmmError as error:
            error_message = f"step {k}: {error}"
            break
        time_log[k] = time.perf_counter() - tic
        qdot = output.qdot
        q_log[k] = robot.joint_coordinates(q)
        qdot_log[k] = qdot
        error_log[k] = tracking_error
        sigma_log[k] = state.sigma_min
        if output.reports:
            p_log[k] = max(r.p for r in output.reports)
            active_log[k] = any(r.active for r in output.reports)
            if active_log[k]:
                difference = state.weight * (command - output.xdot_filtered)
                removed_log[k] = math.sqrt(float(difference @ difference))
        damping_log[k] = output.backend.damping
        scale_log[k] = output.backend.scale
        weak_log[k] = abs(float(state.weakest_joint_direction @ qdot))
        status_log[k] = output.backend.status
        positions.append(task_position(state.x).copy())
        desired.append(task_position(xd).copy())
        q = robot.integrate(q, qdot, dt)
        qdot_prev = qdot
        done = k + 1

    def cut(a: np.ndarray) -> np.ndarray:
        return a[:done]

    d = 3 if robot.task_kind == "pose" else n
    return RunResult(
        experiment=experiment,
        controller=controller.name,
        loop_mode=loop_mode,
        dt=dt,
        joint_names=robot.joint_names,
        task_kind=robot.task_kind,
        t=cut(t),
        q=cut(q_log),
        qdot=cut(qdot_log),
        position=np.array(positions).reshape(done, d),
        position_desired=np.array(desired).reshape(done, d),
        error=cut(error_log),
        sigma_min=cut(sigma_log),
        p=cut(p_log),
        filter_active=cut(active_log),
        removed=cut(removed_log),
        damping=cut(damping_log),
        scale=cut(scale_log),
        weak_speed=cut(weak_log),
        status=cut(status_log),
        step_time=cut(time_log),
        position_limits=robot.position_limits,
        velocity_limits=robot.velocity_limits,
        filters="+".join(f.name for f in controller.filters) or "none",
        backend=controller.backend.name,
        error_message=error_message,
    )
