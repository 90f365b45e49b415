"""The closed simulation loop: state → command → filters → backend → Euler step."""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from otmm_qp.conditioning.pipeline import Conditioning
from otmm_qp.controller import Controller, ControllerOutput
from otmm_qp.exceptions import DimensionError, InfeasibleProblem, OtmmError, ParameterError
from otmm_qp.plants.chain import PlantChain
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.simulation.loop_modes import LOOP_MODES, LoopMode, commanded_velocity
from otmm_qp.simulation.recorder import RunRecorder, task_position
from otmm_qp.simulation.run_result import RunResult
from otmm_qp.state import KinematicState
from otmm_qp.trajectories.trajectory import Trajectory

__all__ = ["StepObserver", "check_run_arguments", "simulate", "task_position"]

#: Called after every completed step with ``(k, state, command ẋ_c, q̇_prev, output)``.
StepObserver = Callable[[int, KinematicState, FloatArray, FloatArray, ControllerOutput], None]


def _positive_finite(name: str, value: float, allow_zero: bool = False) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ParameterError(name, f"must be a number, got {value!r:.40}") from None
    if not math.isfinite(number) or number < 0.0 or (number == 0.0 and not allow_zero):
        allowed = ">= 0" if allow_zero else "> 0"
        raise ParameterError(name, f"must be a finite number {allowed}, got {number}")
    return number


def check_run_arguments(
    robot: Robot,
    q0: FloatArray,
    dt: float,
    duration: float,
    loop_mode: str,
    clik_gain: float,
    task_weight: FloatArray | None,
) -> tuple[FloatArray, int, FloatArray | None]:
    """Validate the arguments of :func:`simulate` once per run.

    Returns:
        ``(q0 as a float array (nq,), number of steps, task weight (n,) or None)``.

    Raises:
        ParameterError: ``dt``, ``duration``, ``clik_gain``, ``loop_mode`` or ``task_weight``
            out of range (naming the argument).
        DimensionError: ``q0`` or ``task_weight`` of the wrong shape.
    """
    dt = _positive_finite("dt", dt)
    duration = _positive_finite("duration", duration, allow_zero=True)
    _positive_finite("clik_gain", clik_gain, allow_zero=True)
    if loop_mode not in LOOP_MODES:
        raise ParameterError("loop_mode", f"must be one of {', '.join(LOOP_MODES)}")
    q = np.array(q0, dtype=float)
    if q.shape != (robot.nq,):
        raise DimensionError("q0", (robot.nq,), q.shape)
    weight = None
    if task_weight is not None:
        weight = np.asarray(task_weight, dtype=float)
        if weight.shape != (robot.task_dim,):
            raise DimensionError("task_weight", (robot.task_dim,), weight.shape)
        if not np.all(np.isfinite(weight) & (weight > 0.0)):
            raise ParameterError("task_weight", "every weight must be a finite number > 0")
    return q, max(1, int(round(duration / dt))), weight


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
    *,
    on_step: StepObserver | None = None,
    plant: PlantChain | None = None,
    conditioning: Conditioning | None = None,
) -> RunResult:
    r"""Run ``controller`` on ``robot`` along ``trajectory`` with explicit Euler integration.

    .. math:: q_{k+1} = q_k \oplus \dot q_k\,dt,\qquad \dot q_{-1} = 0

    Args:
        robot: The arm.
        controller: Filters + backend.
        trajectory: Desired motion.
        q0: Start configuration, shape ``(nq,)`` (already checked against limits).
        dt: Control period [s], finite and > 0.
        duration: Simulated time [s], finite and >= 0; ``max(1, round(duration/dt))`` steps.
        loop_mode: How ``ẋ_c`` is formed (see :mod:`otmm_qp.simulation.loop_modes`).
        clik_gain: CLIK gain K [1/s].
        task_weight: Diagonal task weight ``W``, shape ``(n,)``, finite and > 0.
        experiment: Experiment name recorded in the result.
        on_step: Observer called after each step (e.g. to keep the states a benchmark replays).
        plant: What happens between the command and the next state
            (:mod:`otmm_qp.plants`); None is the ideal plant, ``q ⊕ q̇ dt``, bit for bit.
        conditioning: Command stages applied to the controller's ``q̇`` before the plant
            (:mod:`otmm_qp.conditioning`); None: none.

    Returns:
        The time series. A typed error inside the loop (e.g. an infeasible QP with the
        ``raise`` policy, or a non-finite ``q0``) stops the run early; the steps done so far
        are kept and ``error_message`` says why.

    Raises:
        ParameterError: ``dt``, ``duration``, ``clik_gain``, ``loop_mode`` or ``task_weight``
            out of range.
        DimensionError: ``q0`` or ``task_weight`` of the wrong shape.
    """
    q, weight, recorder = _start_run(
        robot, controller, q0, dt, duration, loop_mode, clik_gain, task_weight
    )
    stage = _start_plant(robot, q, dt, plant, conditioning)
    error_message = _run_steps(
        robot, controller, trajectory, q, weight, recorder, loop_mode, dt, clik_gain, on_step,
        stage,
    )  # fmt: skip
    return recorder.result(controller, loop_mode, dt, experiment, error_message, stage)


def _start_plant(
    robot: Robot,
    q: FloatArray,
    dt: float,
    plant: PlantChain | None,
    conditioning: Conditioning | None,
) -> tuple[PlantChain, Conditioning]:
    """The run's plant and conditioning (ideal and none by default), reset at ``q`` (nq,)."""
    plant = plant if plant is not None else PlantChain()
    conditioning = conditioning if conditioning is not None else Conditioning()
    if np.all(np.isfinite(q)):
        plant.reset(robot, q, dt)
    conditioning.reset(robot, dt)
    return plant, conditioning


def _start_run(
    robot: Robot,
    controller: Controller,
    q0: FloatArray,
    dt: float,
    duration: float,
    loop_mode: str,
    clik_gain: float,
    task_weight: FloatArray | None,
) -> tuple[FloatArray, FloatArray | None, RunRecorder]:
    """Validate the arguments, bind ``controller``, size the recorder: ``(q, weight, recorder)``."""
    q, steps, weight = check_run_arguments(
        robot, q0, dt, duration, loop_mode, clik_gain, task_weight
    )
    controller.bind(robot, dt)
    return q, weight, RunRecorder(robot, steps, dt)


def _run_steps(
    robot: Robot,
    controller: Controller,
    trajectory: Trajectory,
    q: FloatArray,
    weight: FloatArray | None,
    recorder: RunRecorder,
    loop_mode: LoopMode,
    dt: float,
    clik_gain: float,
    on_step: StepObserver | None,
    stage: tuple[PlantChain, Conditioning],
) -> str | None:
    """The control loop from ``q``, filling ``recorder``; why it stopped early, or None.

    The controller sees ``plant.measure(q)``; the recorder logs the true state; the
    conditioned command goes through ``plant.advance`` (the one place ``q`` is updated).
    """
    plant, conditioning = stage
    qdot_prev = np.zeros(robot.nv)
    error_message = None if np.all(np.isfinite(q)) else "q0: contains NaN or inf; no step taken"
    for k in range(len(recorder.t) if error_message is None else 0):
        tk = float(recorder.t[k])
        desired, desired_velocity = trajectory.sample(tk)
        tic = time.perf_counter()
        try:
            state = KinematicState.compute(robot, plant.measure(q), weight)
            tracking_error = robot.task_error(desired, state.x)
            command = commanded_velocity(
                loop_mode, robot, trajectory, tk, dt, state.x, tracking_error,
                desired_velocity, clik_gain,
            )  # fmt: skip
            output = controller.step(state, command, qdot_prev)
            qdot = conditioning.apply(state.q, output.qdot)
            true_state = state
            if not plant.exact_measurement:  # metrics on the true state, never the measured one
                true_state = KinematicState.compute(robot, q, weight)
                tracking_error = robot.task_error(desired, true_state.x)
        except InfeasibleProblem as error:
            error_message = str(InfeasibleProblem(k, error.detail))
            break
        except OtmmError as error:
            error_message = f"step {k}: {error}"
            break
        seconds = time.perf_counter() - tic
        recorder.record(k, true_state, command, tracking_error, desired, output, seconds)
        if on_step is not None:
            on_step(k, state, command, qdot_prev, output)
        step = plant.advance(q, qdot)
        recorder.record_plant(k, qdot, step, conditioning.active)
        if not step.stable:
            error_message = f"step {k}: plant {plant.label()} unstable: {step.detail}"
            break
        q = step.q
        qdot_prev = qdot
    return error_message
