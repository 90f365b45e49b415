r"""The one place the next state is made from the controller's ``q̇``: the integration stage.

The loop calls :meth:`Integrator.advance` once per step, after the controller; a stage that
acts between the commanded ``q̇`` and the next state (actuator lag, delay, sensor noise, a
physics engine) is a subclass passed to :func:`~otmm_qp.simulation.simulate.simulate`.
"""

from __future__ import annotations

from otmm_qp.robots.robot import FloatArray, Robot


class Integrator:
    r"""Explicit Euler on the configuration: :math:`q_{k+1} = q_k \oplus \dot q_k\,dt`.

    :meth:`start` is called once per run before the first step, so one instance may serve
    many runs (state a subclass keeps is reset there).
    """

    def __init__(self) -> None:
        self._robot: Robot | None = None
        self._dt = 0.0

    def start(self, robot: Robot, dt: float) -> None:
        """Bind to the run's arm and control period ``dt`` [s]."""
        self._robot = robot
        self._dt = dt

    def advance(self, q: FloatArray, qdot: FloatArray) -> FloatArray:
        r"""Next configuration :math:`q \oplus \dot q\,dt`, shape ``(nq,)``.

        Args:
            q: Configuration at step k, shape ``(nq,)``.
            qdot: Joint velocity the controller returned for step k [rad/s], shape ``(nv,)``.
        """
        if self._robot is None:
            raise RuntimeError("Integrator.advance before start()")
        return self._robot.integrate(q, qdot, self._dt)
