"""The trajectory interface: desired task value and velocity, analytic in time."""

from __future__ import annotations

import abc
from collections.abc import Sequence
from typing import ClassVar

from otmm_qp.robots.robot import FloatArray


class Trajectory(abc.ABC):
    """Desired task motion ``x_d(t)``, ``ẋ_d(t)``.

    Plugins are constructed as ``Trajectory(start=x0, **params)`` where ``x0`` is the task
    value at the start configuration (so a circle can start at the point nearest to it and a
    pose trajectory can keep the start orientation). A trajectory that needs more of the
    experiment names it in ``framework_parameters``: ``robot`` (the experiment's
    :class:`~otmm_qp.robots.robot.Robot`) and ``q0`` (its start configuration, shape
    ``(nq,)``) are passed too; a config never gives them.

    Information is explicit: at time ``t`` a controller may read ``x_d(t + τ)`` only for
    ``0 ≤ τ ≤`` :attr:`lookahead` (:mod:`otmm_qp.trajectories.preview`). The default, 0, is a
    *causal* motion (only the present is known: a teleoperated target, a live stream); a
    planned motion known in full (every built-in analytic path) declares ``inf``.

    Attributes:
        duration: Natural duration [s] (one period, the motion time), used when the
            experiment gives none.
    """

    #: The class's own name (e.g. ``"circle"``), a class constant never assigned on an instance.
    name: ClassVar[str] = "trajectory"
    #: How far ahead [s] the motion is known at any time (0: causal; inf: planned in full).
    lookahead: float = 0.0
    #: Constructor parameters the framework passes itself (never from a config).
    framework_parameters: ClassVar[tuple[str, ...]] = ("start",)
    duration: float

    @abc.abstractmethod
    def sample(self, t: float) -> tuple[FloatArray, FloatArray]:
        """Desired task value and task velocity at time ``t`` [s].

        Returns:
            ``(x_d, ẋ_d)``: task value (same kind as ``Robot.kinematics``) and its velocity,
            shape ``(n,)`` (for poses: linear [m/s] then angular [rad/s], world-aligned).
        """

    def position(self, t: float) -> FloatArray:
        """Desired task value at ``t`` [s]."""
        return self.sample(t)[0]

    def positions(self, times: Sequence[float]) -> list[FloatArray]:
        """Desired task values at each of ``times`` [s] (a preview window's knots).

        The default calls :meth:`position` per time; a motion with a closed form overrides it
        to evaluate the window at once (equal to :meth:`position` up to rounding).
        """
        return [self.position(t) for t in times]
