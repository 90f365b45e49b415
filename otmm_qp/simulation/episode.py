r"""What one run is: a frozen :class:`Loop` and :class:`Episode` that check themselves once.

An episode is everything :func:`~otmm_qp.simulation.simulate.simulate` needs besides the
controller: the arm, the desired motion, the start, the control period, the duration and how
the commanded task velocity is formed. Both the ``run`` and the ``study`` paths build one per
run, so every check below holds for both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from otmm_qp.exceptions import DimensionError, ParameterError
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.simulation.loop_modes import LOOP_MODES, LoopMode, commanded_velocity
from otmm_qp.trajectories.trajectory import Trajectory

#: Default cap on control steps per run or study episode (raise it with ``max_steps``).
DEFAULT_MAX_STEPS = 1_000_000
#: Bytes logged per step and per logged value (time series of floats), for the cap message.
BYTES_PER_VALUE = 8


def finite_number(name: str, value: Any, *, allow_zero: bool = False) -> float:
    """``value`` as a float, refused unless finite and > 0 (or >= 0 with ``allow_zero``).

    Raises:
        ParameterError: Naming ``name``, the value and what is allowed.
    """
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ParameterError(name, f"must be a number, got {value!r:.40}") from None
    if not math.isfinite(number) or number < 0.0 or (number == 0.0 and not allow_zero):
        allowed = ">= 0" if allow_zero else "> 0"
        raise ParameterError(name, f"must be a finite number {allowed}, got {number}")
    return number


def check_task_weight(weight: Any, task_dim: int, name: str = "task_weight") -> FloatArray:
    """A diagonal task weight as a read-only float array of shape ``(task_dim,)``.

    Raises:
        DimensionError: Not of shape ``(task_dim,)``.
        ParameterError: A weight that is not a finite number > 0.
    """
    array = np.array(weight, dtype=float)
    if array.shape != (task_dim,):
        raise DimensionError(name, (task_dim,), array.shape)
    if not np.all(np.isfinite(array) & (array > 0.0)):
        raise ParameterError(name, "every weight must be a finite number > 0")
    array.setflags(write=False)
    return array


def step_count(duration: float, dt: float) -> int:
    """Number of control steps of a run: ``max(1, round(duration/dt))``."""
    return max(1, int(round(duration / dt)))


def check_step_cap(steps: float, max_steps: int, values_per_step: int, name: str) -> None:
    """Refuse more than ``max_steps`` control steps, saying how much memory they would take.

    Args:
        steps: ``duration/dt`` (may be huge or inf).
        max_steps: The cap.
        values_per_step: Floats logged per step (for the memory estimate).
        name: Field named in the message.

    Raises:
        ParameterError: On ``name``, with the memory the logs would need.
    """
    if math.isfinite(steps) and steps <= max_steps:
        return
    gib = steps * values_per_step * BYTES_PER_VALUE / 2**30 if math.isfinite(steps) else math.inf
    raise ParameterError(
        name,
        f"duration/dt = {steps:.3g} steps per run exceeds max_steps = {max_steps} "
        f"(the logs would take about {gib:.3g} GiB per run); shorten duration, raise dt, "
        "or raise max_steps (config key, or --max-steps) explicitly",
    )


def logged_values(robot: Robot) -> int:
    """Floats logged per step for ``robot`` (joint and task coordinates plus scalars)."""
    return 3 * robot.nv + 4 * robot.task_dim + 12


@dataclass(frozen=True)
class Loop:
    r"""How the commanded task velocity ``ẋ_c`` [task units/s] is formed each step.

    * ``feedforward``: :math:`\dot x_c = \dot x_d(t_k)`;
    * ``clik``: :math:`\dot x_c = \dot x_d(t_k) + K\,e(x_d(t_k), x_k)`;
    * ``newton``: :math:`\dot x_c = e(x_d(t_{k+1}), x_k)/dt`.

    Attributes:
        mode: Loop mode, one of :data:`~otmm_qp.simulation.loop_modes.LOOP_MODES`.
        gain: CLIK gain K [1/s], finite and >= 0 (used by ``clik`` only).

    Raises:
        ParameterError: Unknown mode or a gain that is not a finite number >= 0.
    """

    mode: LoopMode = "clik"
    gain: float = 10.0

    def __post_init__(self) -> None:
        if self.mode not in LOOP_MODES:
            raise ParameterError(
                "loop_mode", f"must be one of {', '.join(LOOP_MODES)}, got {self.mode!r:.40}"
            )
        object.__setattr__(self, "gain", finite_number("clik_gain", self.gain, allow_zero=True))

    def command(
        self,
        robot: Robot,
        trajectory: Trajectory,
        t: float,
        dt: float,
        x: FloatArray,
        error: FloatArray,
        xd_dot: FloatArray,
    ) -> FloatArray:
        """Commanded task velocity ``ẋ_c``, shape ``(n,)``.

        Args:
            robot: The arm (for its task error; ``newton`` only).
            trajectory: Desired motion (``newton`` samples it at ``t + dt``).
            t: Current time [s].
            dt: Control period [s].
            x: Current task value.
            error: Tracking error ``e(x_d(t), x)``, shape ``(n,)``.
            xd_dot: Desired task velocity at ``t``, shape ``(n,)``.
        """
        return commanded_velocity(self.mode, robot, trajectory, t, dt, x, error, xd_dot, self.gain)


@dataclass(frozen=True)
class Episode:
    r"""One run's inputs besides the controller; checked once, when it is made.

    The run takes :attr:`steps` = ``max(1, round(duration/dt))`` steps at ``t_k = k·dt``.

    Attributes:
        robot: The arm.
        trajectory: Desired motion.
        q0: Start configuration, shape ``(nq,)`` (a read-only float copy; a non-finite q0 is
            accepted here and ends the run before its first step, with a message).
        dt: Control period [s], finite and > 0.
        duration: Simulated time [s], finite and >= 0.
        loop: How ``ẋ_c`` is formed.
        task_weight: Diagonal task weight ``W``, shape ``(n,)``, finite and > 0, or None.
        name: Experiment name recorded in the result.
        max_steps: Cap on :attr:`steps` (default :data:`DEFAULT_MAX_STEPS`).

    Raises:
        ParameterError: ``dt``, ``duration``, ``task_weight`` or ``max_steps`` out of range,
            or more than ``max_steps`` steps (naming the memory the logs would need).
        DimensionError: ``q0`` or ``task_weight`` of the wrong shape.
    """

    robot: Robot
    trajectory: Trajectory
    q0: FloatArray
    dt: float
    duration: float
    loop: Loop = field(default_factory=Loop)
    task_weight: FloatArray | None = None
    name: str = ""
    max_steps: int = DEFAULT_MAX_STEPS

    def __post_init__(self) -> None:
        dt = finite_number("dt", self.dt)
        duration = finite_number("duration", self.duration, allow_zero=True)
        if not isinstance(self.max_steps, int) or self.max_steps <= 0:
            raise ParameterError("max_steps", f"must be an integer > 0, got {self.max_steps!r:.40}")
        if not isinstance(self.loop, Loop):
            raise ParameterError("loop", f"must be a Loop, got {type(self.loop).__name__}")
        q0 = np.array(self.q0, dtype=float)
        if q0.shape != (self.robot.nq,):
            raise DimensionError("q0", (self.robot.nq,), q0.shape)
        q0.setflags(write=False)
        weight = self.task_weight
        if weight is not None:
            weight = check_task_weight(weight, self.robot.task_dim)
        check_step_cap(duration / dt, self.max_steps, logged_values(self.robot), "duration")
        object.__setattr__(self, "dt", dt)
        object.__setattr__(self, "duration", duration)
        object.__setattr__(self, "q0", q0)
        object.__setattr__(self, "task_weight", weight)

    @property
    def steps(self) -> int:
        """Number of control steps: ``max(1, round(duration/dt))``."""
        return step_count(self.duration, self.dt)
