r"""How the commanded task velocity ``ẋ_c`` is formed each step (the paper does not say).

* ``feedforward``: :math:`\dot x_c = \dot x_d(t_k)` — pure RMRC, errors accumulate.
* ``clik``: :math:`\dot x_c = \dot x_d(t_k) + K\,e(x_d(t_k), x_k)` — closed-loop IK, gain K [1/s].
* ``newton``: :math:`\dot x_c = e(x_d(t_{k+1}), x_k)/dt` — aim at the next sample
  (the "basic Newton algorithm" the paper names for Fig. 2).

``e`` is :meth:`Robot.task_error` (a difference for points, the log map for poses).
"""

from __future__ import annotations

from typing import Literal

from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.trajectories.trajectory import Trajectory

LoopMode = Literal["feedforward", "clik", "newton"]
LOOP_MODES: tuple[LoopMode, ...] = ("feedforward", "clik", "newton")


def commanded_velocity(
    mode: LoopMode,
    robot: Robot,
    trajectory: Trajectory,
    t: float,
    dt: float,
    x: FloatArray,
    error: FloatArray,
    xd_dot: FloatArray,
    gain: float,
) -> FloatArray:
    """Commanded task velocity ``ẋ_c`` [task units/s], shape ``(n,)``.

    Args:
        mode: Loop mode.
        robot: The arm (for its task error).
        trajectory: Desired motion (``newton`` samples it at ``t + dt``).
        t: Current time [s].
        dt: Control period [s].
        x: Current task value.
        error: Tracking error ``e(x_d(t), x)``, shape ``(n,)`` (computed once per step by the
            caller, which also records it).
        xd_dot: Desired task velocity at ``t``, shape ``(n,)``.
        gain: CLIK gain K [1/s].
    """
    if mode == "feedforward":
        return xd_dot
    if mode == "clik":
        return xd_dot + gain * error
    return robot.task_error(trajectory.position(t + dt), x) / dt
