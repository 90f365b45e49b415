r"""The closed simulation loop: state → command → filters → backend → plant.

.. math:: q_{k+1} = q_k \oplus \dot q_k\,dt,\qquad \dot q_{-1} = 0

Backends, filters, trajectories and robots are plugins, i.e. untrusted code: any exception
they raise inside a step (``SystemExit`` included; ``KeyboardInterrupt`` stays an interrupt)
and any malformed ``q̇`` (not a float array of shape ``(nv,)``) stops that run with a message
and keeps its earlier steps, so the other runs of a suite or study go on.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from otmm_qp.conditioning.pipeline import Conditioning
from otmm_qp.controller import Controller, ControllerOutput
from otmm_qp.exceptions import InfeasibleProblem, OtmmError, SolverNotConverged
from otmm_qp.plants.chain import PlantChain
from otmm_qp.plants.ideal import IdealPlant
from otmm_qp.plants.plant import PlantStep
from otmm_qp.robots.robot import FloatArray
from otmm_qp.simulation.episode import Episode
from otmm_qp.simulation.recorder import RunRecorder, task_position
from otmm_qp.simulation.run_result import RunResult
from otmm_qp.state import KinematicState

__all__ = ["StepObserver", "failure_message", "simulate", "task_position"]

#: Called after every completed step with ``(k, state, command ẋ_c, q̇_prev, output)``.
StepObserver = Callable[[int, KinematicState, FloatArray, FloatArray, ControllerOutput], None]

#: Longest plugin message kept in a run's ``error_message`` [characters].
MESSAGE_LIMIT = 300


class MalformedOutput(OtmmError):
    """A plugin returned an array that is not a finite float array of the expected shape.

    A backend (or filter) a ``q̇`` that is not of shape ``(nv,)``, or a plant stage a next
    state ``q`` not of shape ``(nq,)`` or an actual velocity not of shape ``(nv,)``.
    """


def failure_message(k: int, error: BaseException) -> str:
    """``step k: ...`` on one line for an error raised inside step ``k``."""
    if isinstance(error, InfeasibleProblem):
        return str(InfeasibleProblem(k, error.detail))
    if isinstance(error, SolverNotConverged):
        return str(SolverNotConverged(k, error.detail))
    text = " ".join(str(error).split())[:MESSAGE_LIMIT]
    if isinstance(error, OtmmError):
        return f"step {k}: {text}"
    kind = type(error).__name__
    return (
        f"step {k}: a plugin raised {kind}: {text}" if text else f"step {k}: a plugin raised {kind}"
    )


def _checked_qdot(output: ControllerOutput, nv: int) -> FloatArray:
    """``output.qdot`` when it is a float array of shape ``(nv,)``; else MalformedOutput."""
    qdot = output.qdot
    if type(qdot) is not np.ndarray or qdot.shape != (nv,) or qdot.dtype.kind != "f":
        shape = getattr(qdot, "shape", None)
        raise MalformedOutput(
            f"the backend returned q̇ of type {type(qdot).__name__}"
            + (f" and shape {shape}" if shape is not None else "")
            + f"; expected a float array of shape ({nv},)"
        )
    return qdot


def _checked_step(step: PlantStep, nq: int, nv: int) -> PlantStep:
    """``step`` if its ``q`` (nq,) and ``qdot`` (nv,) are finite float arrays; else raise.

    One test and two dot products in the common case (~2 µs; NaN/inf make the sum
    non-finite); the element-wise tests only word the message, so a finite state beyond
    1e154 still passes (numpy then warns of the overflow in the dot product).

    Raises:
        MalformedOutput: Naming the field, its type and shape, or that it holds NaN/inf.
    """
    q, qdot = step.q, step.qdot
    if (
        type(q) is np.ndarray
        and type(qdot) is np.ndarray
        and q.shape == (nq,)
        and qdot.shape == (nv,)
        and q.dtype.kind == "f"
        and qdot.dtype.kind == "f"
        and math.isfinite(float(q.dot(q)) + float(qdot.dot(qdot)))
    ):
        return step
    for field, value, size in (("q", q, nq), ("qdot", qdot, nv)):
        if type(value) is not np.ndarray or value.shape != (size,) or value.dtype.kind != "f":
            shape = getattr(value, "shape", None)
            raise MalformedOutput(
                f"the plant returned {field} of type {type(value).__name__}"
                + (f" and shape {shape}" if shape is not None else "")
                + f"; expected a float array of shape ({size},)"
            )
        if not np.all(np.isfinite(value)):
            raise MalformedOutput(f"the plant returned {field} containing NaN or inf")
    return step


def simulate(
    episode: Episode,
    controller: Controller,
    *,
    on_step: StepObserver | None = None,
    plant: PlantChain | None = None,
    conditioning: Conditioning | None = None,
) -> RunResult:
    r"""Run ``controller`` on ``episode``.

    Each step k: :math:`x_k, J_k` and the SVD once (:class:`KinematicState`), the command
    ``ẋ_c`` from the episode's :class:`~otmm_qp.simulation.episode.Loop`, the controller's
    ``q̇_k``, then ``plant.advance(q_k, q̇_k)`` for :math:`q_{k+1}` (the one place the next
    state is made).

    Args:
        episode: What to run (checked when it was made).
        controller: Filters + backend; bound to the episode's robot and ``dt`` here.
        on_step: Observer called after each step (e.g. to keep the states a benchmark replays).
        plant: What happens between the command and the next state (:mod:`otmm_qp.plants`:
            lag, delay, sensor noise, MuJoCo, or any :class:`~otmm_qp.plants.plant.Plant`);
            None is ``PlantChain([IdealPlant()])``, explicit Euler
            :math:`q \oplus \dot q\,dt`. The controller sees ``plant.measure(q)``; the
            results and metrics the true ``q``.
        conditioning: Command stages applied to the controller's ``q̇`` before the plant
            (:mod:`otmm_qp.conditioning`); None: none.

    Returns:
        The time series. An error inside a step (an infeasible QP with the ``raise`` policy,
        any exception from a plugin, a malformed ``q̇``) or a non-finite ``q0`` stops the run
        early; the steps done so far are kept and ``error_message`` says why.
    """
    robot, dt = episode.robot, episode.dt
    plant = plant if plant is not None else PlantChain([IdealPlant()])
    controller.declare_plant(plant.declares(dt))
    controller.bind(robot, dt, episode.trajectory)
    conditioning = conditioning if conditioning is not None else Conditioning()
    if np.all(np.isfinite(episode.q0)):
        plant.reset(robot, episode.q0, dt)
    conditioning.reset(robot, dt)
    recorder = RunRecorder(robot, episode.steps, dt)
    error_message = _run_steps(episode, controller, recorder, (plant, conditioning), on_step)
    return recorder.result(
        controller, episode.loop.mode, dt, episode.name, error_message, (plant, conditioning)
    )


def _run_steps(
    episode: Episode,
    controller: Controller,
    recorder: RunRecorder,
    stage: tuple[PlantChain, Conditioning],
    on_step: StepObserver | None,
) -> str | None:
    """The control loop from ``episode.q0``, filling ``recorder``; why it stopped, or None.

    The controller sees ``plant.measure(q)``; the recorder logs the true state; the
    conditioned command goes through ``plant.advance``, the one place ``q`` is updated.
    """
    plant, conditioning = stage
    robot, trajectory, dt, weight = (
        episode.robot,
        episode.trajectory,
        episode.dt,
        episode.task_weight,
    )
    command_of, nq, nv = episode.loop.command, robot.nq, robot.nv
    q = np.array(episode.q0)
    qdot_prev = np.zeros(nv)
    if not np.all(np.isfinite(q)):
        return "q0: contains NaN or inf; no step taken"
    for k in range(len(recorder.t)):
        tk = float(recorder.t[k])
        try:
            desired, desired_velocity = trajectory.sample(tk)
            tic = time.perf_counter()
            state = KinematicState.compute(robot, plant.measure(q), weight)
            tracking_error = robot.task_error(desired, state.x)
            command = command_of(
                robot, trajectory, tk, dt, state.x, tracking_error, desired_velocity
            )
            output = controller.step(state, command, qdot_prev)
            qdot = conditioning.apply(state.q, _checked_qdot(output, nv))
            seconds = time.perf_counter() - tic
            true_state = state
            if not plant.exact_measurement:  # metrics on the true state, never the measured one
                true_state = KinematicState.compute(robot, q, weight)
                tracking_error = robot.task_error(desired, true_state.x)
            recorder.record(k, true_state, command, tracking_error, desired, output, seconds)
        except (Exception, SystemExit) as error:  # plugins are untrusted code
            return failure_message(k, error)
        if on_step is not None:
            on_step(k, state, command, qdot_prev, output)
        try:
            step = plant.advance(q, qdot)
            if step.stable:
                step = _checked_step(step, nq, nv)
        except (Exception, SystemExit) as error:  # a plant stage or a robot's integrate
            return failure_message(k + 1, error)
        recorder.record_plant(k, qdot, step, conditioning.active)
        if not step.stable:
            return f"step {k}: plant {plant.label()} unstable: {step.detail}"
        q = step.q
        qdot_prev = qdot
    return None
