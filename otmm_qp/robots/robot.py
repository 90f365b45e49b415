"""The robot interface every arm implements (planar, Pinocchio, third party)."""

from __future__ import annotations

import abc
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from otmm_qp.exceptions import DimensionError, NotWithinJointLimits, RobotLoadError
from otmm_qp.robots.peer_description import PeerDescription

FloatArray = NDArray[np.float64]
TaskKind = Literal["position", "pose"]


class Robot(abc.ABC):
    """A kinematic chain seen by a velocity-level IK controller.

    Conventions:
        * ``q`` is the configuration vector, shape ``(nq,)``; ``v`` a joint velocity, shape
          ``(nv,)``. For revolute and prismatic joints ``nq == nv``; continuous joints
          stored as (cos, sin) make ``nq > nv``.
        * Joint coordinates (angles [rad] / positions [m]), shape ``(nv,)``, are what
          configs, limits and time series use; :meth:`configuration` and
          :meth:`joint_coordinates` convert.
        * The task value ``x`` returned by :meth:`kinematics` may be any array (a point
          ``(n,)`` or a homogeneous pose ``(4, 4)``); :meth:`task_error` maps two task values
          to a vector of shape ``(n,)`` in the frame of the Jacobian.

    Subclasses implement :meth:`kinematics` and the limit attributes; to run with the peer
    backends (pink, mink, Drake) they also implement :meth:`peer_description`.
    """

    #: Human-readable robot name.
    name: str = "robot"
    #: ``"position"``: x ∈ Rⁿ; ``"pose"``: x ∈ SE(3), error = (linear [m], angular [rad]).
    task_kind: TaskKind = "position"

    @property
    @abc.abstractmethod
    def joint_names(self) -> tuple[str, ...]:
        """Names of the ``nv`` joints."""

    @property
    @abc.abstractmethod
    def task_dim(self) -> int:
        """Task dimension ``n`` (rows of the Jacobian)."""

    @property
    @abc.abstractmethod
    def position_limits(self) -> tuple[FloatArray, FloatArray]:
        """Joint position limits ``(lower, upper)`` [rad or m], shapes ``(nv,)``; ±inf: none."""

    @property
    @abc.abstractmethod
    def velocity_limits(self) -> FloatArray:
        """Joint speed limits [rad/s or m/s], shape ``(nv,)``; inf when unbounded."""

    @abc.abstractmethod
    def kinematics(self, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        r"""Task value and Jacobian at ``q``.

        .. math:: x = f(q), \qquad J = \partial f / \partial q \in \mathbb{R}^{n \times nv}

        Args:
            q: Configuration, shape ``(nq,)``.

        Returns:
            ``(x, J)``: the task value and the Jacobian, shape ``(n, nv)``.
        """

    # ----------------------------------------------------------------- defaults
    @property
    def nv(self) -> int:
        """Number of joint velocity coordinates."""
        return len(self.joint_names)

    @property
    def nq(self) -> int:
        """Size of the configuration vector."""
        return self.nv

    def forward(self, q: FloatArray) -> FloatArray:
        """Task value ``x = f(q)``."""
        return self.kinematics(q)[0]

    def jacobian(self, q: FloatArray) -> FloatArray:
        """Jacobian ``J(q)``, shape ``(n, nv)``."""
        return self.kinematics(q)[1]

    def jacobian_derivative(self, q: FloatArray, direction: FloatArray) -> FloatArray:
        r"""Directional derivative of the Jacobian along a joint velocity, shape ``(n, nv)``.

        .. math:: \dot J(q, d) = \sum_k \frac{\partial J}{\partial q_k} d_k
                  = \lim_{h\to 0} \frac{J(q \oplus h d) - J(q \ominus h d)}{2h}

        With ``d = q̇`` [rad/s] this is ``dJ/dt`` [task units/s per rad/s]. The default is the
        central difference above (step ``h = 1e-6 / max(1, ‖d‖)``, error O(h²)); subclasses
        override it with an analytic form when they have one.

        Args:
            q: Configuration, shape ``(nq,)``.
            direction: Joint velocity ``d``, shape ``(nv,)``.
        """
        d = np.asarray(direction, dtype=float)
        h = 1e-6 / max(1.0, float(np.linalg.norm(d)))
        forward = self.jacobian(self.integrate(q, d, h))
        backward = self.jacobian(self.integrate(q, d, -h))
        return np.asarray((forward - backward) / (2.0 * h), dtype=float)

    def task_error(self, x_target: FloatArray, x: FloatArray) -> FloatArray:
        """Error that drives ``x`` toward ``x_target``, shape ``(n,)``: ``x_target − x``."""
        return np.asarray(x_target, dtype=float) - np.asarray(x, dtype=float)

    def integrate(self, q: FloatArray, v: FloatArray, dt: float) -> FloatArray:
        """Explicit Euler step ``q ← q ⊕ v·dt`` (``dt`` in [s])."""
        return q + v * dt

    def configuration(self, joint_coordinates: FloatArray) -> FloatArray:
        """Configuration ``q`` (nq,) from joint coordinates (nv,)."""
        return np.array(joint_coordinates, dtype=float)

    def joint_coordinates(self, q: FloatArray) -> FloatArray:
        """Joint coordinates (nv,) of configuration ``q`` (nq,)."""
        return np.array(q, dtype=float)

    def can_reach(self, x: FloatArray) -> bool:
        """Whether the task value ``x`` lies in the workspace (default: unknown, so True)."""
        return True

    def check_start(self, joint_coordinates: FloatArray) -> FloatArray:
        """Validate a start ``q0`` given in joint coordinates and return it as a configuration.

        Raises:
            DimensionError: ``q0`` has the wrong length.
            NotWithinJointLimits: a joint is outside its position limits.
        """
        q0 = np.asarray(joint_coordinates, dtype=float)
        if q0.shape != (self.nv,):
            raise DimensionError("q0", (self.nv,), q0.shape)
        lower, upper = self.position_limits
        for name, value, lo, hi in zip(self.joint_names, q0, lower, upper, strict=True):
            if not (lo - 1e-12 <= value <= hi + 1e-12):
                raise NotWithinJointLimits(name, float(value), float(lo), float(hi))
        return self.configuration(q0)

    def peer_description(self) -> PeerDescription:
        """The URDF, end-effector frame and joint names a peer IK library models this arm from.

        Called once when a peer backend is bound to the robot (not per step). The default
        refuses: a robot runs with the peers only if it describes itself.

        Raises:
            RobotLoadError: Always, in the default (one line, naming the robot and its class).
        """
        raise RobotLoadError(
            f"robot {self.name!r} ({type(self).__qualname__}) cannot be modelled by a peer "
            "(pink, mink, drake): implement peer_description() returning an "
            "otmm_qp.robots.PeerDescription (URDF text, end-effector frame, joint names)"
        )
