r"""The velocity-level frame task handed to pink and mink: exactly the problem ``qp`` solves.

pink's and mink's ``FrameTask`` linearise the SE(3) log toward a target pose; their task
Jacobian ``−Jlog6(T_tb)·J_b`` depends on the target, so their step differs from ``qp``'s at
first order in ``ẋ·dt`` (about 1 % on the arm scenarios). The adapters instead give the peer,
through its public ``Task`` API, the task the velocity-level controllers solve:

.. math::
    e = -\dot x\,dt,\qquad J_{task} = S\,J_{LWA}(q),\qquad \text{cost} = W

with ``S`` selecting the commanded rows of the ``LOCAL_WORLD_ALIGNED`` frame Jacobian (x, y when
the robot's peer description is planar; the linear rows for position tasks; all six for poses),
computed by the peer from its own model. The peer then minimises, in ``Δq = q̇·dt``,

.. math:: \|W(J_{task}\Delta q + e)\|^2 + \mu\|\Delta q\|^2
          = dt^2\big(\|W(J\dot q - \dot x)\|^2 + \mu\|\dot q\|^2\big)

under its configuration and velocity limits: ``qp``'s problem with ``λ = μ``.
"""

from __future__ import annotations

import numpy as np

from otmm_qp.robots.robot import FloatArray, TaskKind


def task_rows(planar: bool, task_kind: TaskKind) -> np.ndarray:
    """Rows of the 6-D ``(v, ω)`` frame Jacobian the task commands, shape ``(n,)``.

    Args:
        planar: The robot's :attr:`PeerDescription.planar
            <otmm_qp.robots.peer_description.PeerDescription.planar>` (x, y in the world
            xy-plane).
        task_kind: The robot's ``task_kind`` (``"position"`` or ``"pose"``).

    Returns:
        ``[0, 1]`` (planar), ``[0, 1, 2]`` (position) or ``[0, …, 5]`` (pose).
    """
    if planar:
        return np.array([0, 1])
    if task_kind == "pose":
        return np.arange(6)
    return np.arange(3)


class VelocityTaskData:
    """The per-step error ``e = −ẋ·dt`` (n,) and cost ``W`` (n,) shared with the peer task."""

    def __init__(self, rows: np.ndarray) -> None:
        self.rows = rows
        self.error = np.zeros(rows.size)
        self.cost = np.ones(rows.size)

    def set_command(self, xdot: FloatArray, weight: FloatArray, dt: float) -> None:
        """Store ``e = −ẋ·dt`` for the physical command ``ẋ`` (n,) and the task weight (n,)."""
        np.multiply(xdot, -dt, out=self.error)
        self.cost[:] = weight
