"""Time series of one run (one controller, one experiment, one loop mode)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from otmm_qp.robots.robot import FloatArray


@dataclass
class RunResult:
    """Per-step records of a simulated run; step ``k`` is at ``t[k] = k·dt``.

    Attributes:
        experiment: Experiment name.
        controller: Controller label.
        loop_mode: ``feedforward``, ``clik`` or ``newton``.
        dt: Control period [s].
        joint_names: Names of the ``nv`` joints.
        task_kind: ``position`` or ``pose``.
        t: Times [s], shape ``(N,)``.
        q: Joint coordinates at the start of each step [rad], shape ``(N, nv)``.
        qdot: Joint velocities commanded each step [rad/s], shape ``(N, nv)`` (after any
            conditioning; what the ideal plant integrates).
        position: End-effector position [m], shape ``(N, d)`` (d = 2 or 3).
        position_desired: Desired position [m], shape ``(N, d)``.
        error: Task error ``e(x_d, x)``, shape ``(N, n)`` (pose: linear [m], angular [rad]).
        sigma_min: Smallest singular value of ``J_w``, shape ``(N,)``.
        p: Largest filter suppression level, shape ``(N,)``.
        filter_active: Whether any filter changed the command, shape ``(N,)``.
        removed: ‖ẋ_c − ẋ_m‖ (weighted), shape ``(N,)``.
        damping: Backend damping (NaN when none), shape ``(N,)``.
        scale: Fraction of the command realised, shape ``(N,)``.
        weak_speed: Joint speed along the weakest right singular vector ``|v_minᵀq̇|``, ``(N,)``.
        status: Backend status per step, shape ``(N,)``.
        step_time: Wall time of state + controller per step [s], shape ``(N,)``.
        position_limits: ``(lower, upper)`` joint limits [rad], shapes ``(nv,)``.
        velocity_limits: Joint speed limits [rad/s], shape ``(nv,)``.
        error_message: Set when the run stopped early on an error.
        qdot_actual: Joint velocity the plant realised each step [rad/s], ``(N, nv)``
            (:mod:`otmm_qp.plants`; equal to ``qdot`` for the ideal plant).
        torque_ratio: Largest ``|τ|/τ_max`` per step, ``(N,)`` (NaN without a torque model).
        saturated: Whether a joint torque was clipped during the step, ``(N,)``.
        conditioned: Whether a conditioning stage changed the command, ``(N,)``.
        plant: Label of the plant (``ideal`` by default).
        conditioning: Label of the conditioning stages (``none`` by default).
        command_limits: The interface's thresholds on the command stream the plant declares
            (:mod:`otmm_qp.plants.interface`): ``(acceleration [rad/s²], jerk [rad/s³],
            the interface's period [s] (0: the control period))``, the first two each empty
            (none), one value or one per joint.
    """

    experiment: str
    controller: str
    loop_mode: str
    dt: float
    joint_names: tuple[str, ...]
    task_kind: str
    t: FloatArray
    q: FloatArray
    qdot: FloatArray
    position: FloatArray
    position_desired: FloatArray
    error: FloatArray
    sigma_min: FloatArray
    p: FloatArray
    filter_active: np.ndarray
    removed: FloatArray
    damping: FloatArray
    scale: FloatArray
    weak_speed: FloatArray
    status: np.ndarray
    step_time: FloatArray
    position_limits: tuple[FloatArray, FloatArray]
    velocity_limits: FloatArray
    filters: str = ""
    backend: str = ""
    error_message: str | None = None
    extra: dict[str, str] = field(default_factory=dict)
    qdot_actual: FloatArray | None = None
    torque_ratio: FloatArray | None = None
    saturated: np.ndarray | None = None
    conditioned: np.ndarray | None = None
    plant: str = "ideal"
    conditioning: str = "none"
    command_limits: tuple[tuple[float, ...], tuple[float, ...], float] = ((), (), 0.0)

    @property
    def actual_qdot(self) -> FloatArray:
        """Joint velocity the plant realised [rad/s], ``(N, nv)`` (the command when ideal)."""
        return self.qdot if self.qdot_actual is None else self.qdot_actual

    @property
    def plant_columns(self) -> bool:
        """Whether the CSV carries the plant's columns (a non-ideal plant or conditioning)."""
        return self.plant != "ideal" or self.conditioning != "none"

    @property
    def steps(self) -> int:
        """Number of recorded steps."""
        return int(self.t.size)

    @property
    def position_error(self) -> FloatArray:
        """Norm of the linear part of the error [m], shape ``(N,)``."""
        d = 3 if self.task_kind == "pose" else self.error.shape[1]
        return np.asarray(np.linalg.norm(self.error[:, :d], axis=1), dtype=float)

    @property
    def orientation_error(self) -> FloatArray | None:
        """Norm of the angular error [rad], shape ``(N,)``; None for position tasks."""
        if self.task_kind != "pose":
            return None
        return np.asarray(np.linalg.norm(self.error[:, 3:], axis=1), dtype=float)
