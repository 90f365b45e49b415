"""One recorder for the per-step logs of a simulated run (turned into a :class:`RunResult`)."""

from __future__ import annotations

import math

import numpy as np

from otmm_qp.conditioning.pipeline import Conditioning
from otmm_qp.controller import Controller, ControllerOutput
from otmm_qp.plants.chain import PlantChain
from otmm_qp.plants.declaration import PlantDeclaration
from otmm_qp.plants.plant import PlantStep
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.simulation.run_result import RunResult
from otmm_qp.state import KinematicState


def task_position(x: FloatArray) -> FloatArray:
    """Position part of a task value: the point itself, or the translation of a 4×4 pose."""
    return x[:3, 3] if x.ndim == 2 else x


class RunRecorder:
    """Preallocated per-step logs of one run; :meth:`result` cuts them to the steps done.

    Args:
        robot: The arm (joint coordinates, task dimension, limits).
        steps: Largest number of steps the run may take.
        dt: Control period [s]; step ``k`` is at ``t = k·dt``.
    """

    def __init__(self, robot: Robot, steps: int, dt: float) -> None:
        nv, n = robot.nv, robot.task_dim
        self.robot = robot
        self.done = 0
        self.t = np.arange(steps) * dt
        self.q = np.zeros((steps, nv))
        self.qdot = np.zeros((steps, nv))
        self.error = np.zeros((steps, n))
        self.sigma_min = np.zeros(steps)
        self.p = np.zeros(steps)
        self.filter_active = np.zeros(steps, dtype=bool)
        self.removed = np.zeros(steps)
        self.damping = np.full(steps, np.nan)
        self.scale = np.ones(steps)
        self.weak_speed = np.zeros(steps)
        self.status = np.empty(steps, dtype=object)
        self.step_time = np.zeros(steps)
        self.qdot_actual = self.qdot  # the same array until a plant step differs (ideal)
        self.torque_ratio = np.full(steps, np.nan)
        self.saturated = np.zeros(steps, dtype=bool)
        self.conditioned = np.zeros(steps, dtype=bool)
        self.position: list[FloatArray] = []
        self.position_desired: list[FloatArray] = []

    def record(
        self,
        k: int,
        state: KinematicState,
        command: FloatArray,
        tracking_error: FloatArray,
        desired: FloatArray,
        output: ControllerOutput,
        seconds: float,
    ) -> None:
        r"""Log step ``k``.

        ``removed`` is the weighted norm :math:`\|W(\dot x_c - \dot x_m)\|` of what the filters
        took out of the command ``ẋ_c`` (n,) when any was active; ``weak_speed`` is
        :math:`|v_{min}^\top \dot q|` [rad/s].
        """
        qdot = output.qdot
        self.q[k] = self.robot.joint_coordinates(state.q)
        self.qdot[k] = qdot
        self.error[k] = tracking_error
        self.sigma_min[k] = state.sigma_min
        if output.reports:
            self.p[k] = max(r.p for r in output.reports)
            self.filter_active[k] = any(r.active for r in output.reports)
            if self.filter_active[k]:
                difference = state.weight * (command - output.xdot_filtered)
                self.removed[k] = math.sqrt(float(difference @ difference))
        self.damping[k] = output.backend.damping
        self.scale[k] = output.backend.scale
        self.weak_speed[k] = abs(float(state.weakest_joint_direction @ qdot))
        self.status[k] = output.backend.status
        self.step_time[k] = seconds
        self.position.append(task_position(state.x).copy())
        self.position_desired.append(task_position(desired).copy())
        self.done = k + 1

    def record_plant(self, k: int, qdot: FloatArray, step: PlantStep, conditioned: bool) -> None:
        """Log what step ``k`` sent (the conditioned ``qdot`` (nv,)) and what the plant did."""
        if conditioned:
            self.qdot[k] = qdot
            self.conditioned[k] = True
        if step.qdot is not qdot and self.qdot_actual is self.qdot:
            self.qdot_actual = self.qdot.copy()
        self.qdot_actual[k] = step.qdot
        self.torque_ratio[k] = step.torque_ratio
        self.saturated[k] = step.saturated

    def result(
        self,
        controller: Controller,
        loop_mode: str,
        dt: float,
        experiment: str,
        error_message: str | None,
        stage: tuple[PlantChain, Conditioning] | None = None,
    ) -> RunResult:
        """The :class:`RunResult` of the steps recorded so far."""
        done, robot = self.done, self.robot
        plant, conditioning = stage if stage is not None else (PlantChain(), Conditioning())
        d = 3 if robot.task_kind == "pose" else robot.task_dim
        return RunResult(
            experiment=experiment,
            controller=controller.name,
            loop_mode=loop_mode,
            dt=dt,
            joint_names=robot.joint_names,
            task_kind=robot.task_kind,
            t=np.asarray(self.t[:done], dtype=np.float64),
            q=self.q[:done],
            qdot=self.qdot[:done],
            position=np.array(self.position).reshape(done, d),
            position_desired=np.array(self.position_desired).reshape(done, d),
            error=self.error[:done],
            sigma_min=self.sigma_min[:done],
            p=self.p[:done],
            filter_active=self.filter_active[:done],
            removed=self.removed[:done],
            damping=self.damping[:done],
            scale=self.scale[:done],
            weak_speed=self.weak_speed[:done],
            status=self.status[:done],
            step_time=self.step_time[:done],
            position_limits=robot.position_limits,
            velocity_limits=robot.velocity_limits,
            filters="+".join(controller.filter_names) or "none",
            backend=controller.backend_name,
            error_message=error_message,
            qdot_actual=self.qdot_actual[:done],
            torque_ratio=self.torque_ratio[:done],
            saturated=self.saturated[:done],
            conditioned=self.conditioned[:done],
            plant=plant.label(),
            conditioning=conditioning.label(),
            command_limits=_command_limits(plant.declares(dt)),
        )


def _command_limits(
    declaration: PlantDeclaration,
) -> tuple[tuple[float, ...], tuple[float, ...], float]:
    """The interface thresholds of a plant's declaration (``RunResult.command_limits``)."""
    return (
        declaration.interface_acceleration,
        declaration.interface_jerk,
        declaration.interface_period,
    )
