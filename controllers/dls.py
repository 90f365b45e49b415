"""Damped least squares with a fixed damping factor."""

from __future__ import annotations

from numbers import Real
from typing import ClassVar

from otmm_qp.backends.backend import Backend, BackendOutput, svd_work
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.validation import Constraints, Interval, check_params

from .damping import damped_least_squares


class DampedLeastSquaresBackend(Backend):
    r"""DLS (Wampler; Nakamura–Hanafusa), the minimiser of paper eq. (5).

    .. math:: \min_{\dot q}\ \|\dot x - J\dot q\|^2 + \lambda^2\|\dot q\|^2
              \;\Rightarrow\; \dot q = J^\top(JJ^\top + \lambda^2 I)^{-1}\dot x

    Args:
        damping: Damping factor λ ≥ 0 [task units]; λ = 0 is the pseudoinverse.

    ``BackendOutput.damping`` is λ; status ``saturated`` when ``q̇`` exceeds the robot's
    joint speed limits (see :mod:`otmm_qp.status`).
    """

    name = "dls"
    _work: FloatArray | None = None  # svd_work buffers, allocated by bind
    parameter_constraints: ClassVar[Constraints] = {
        "damping": Interval(Real, 0, None, closed="left"),
    }

    def __init__(self, damping: float = 0.05) -> None:
        check_params(self, locals())
        self.damping = float(damping)

    def bind(self, robot: Robot, dt: float) -> None:
        """Attach the robot; allocate the step's SVD buffers (:func:`svd_work`)."""
        super().bind(robot, dt)
        self._work = svd_work(robot)

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Damped solution [rad/s], shape ``(nv,)``."""
        return self.unconstrained_output(
            damped_least_squares(state, xdot, self.damping**2, self._work), self.damping
        )
