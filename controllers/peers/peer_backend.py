r"""Shared machinery of the peer adapters: availability checks and the task-velocity target.

A peer library solves differential IK toward a *target pose*, not a task velocity. Each
step the adapter turns the commanded task velocity :math:`\dot x` into the target the
peer would have reached after one period :math:`dt` if it realised :math:`\dot x` exactly:

.. math::
    p^* = p + v\,dt, \qquad R^* = \exp(\omega\,dt)\,R

(world-aligned linear velocity ``v`` of the frame origin [m/s] and angular velocity ``ω``
[rad/s], the convention of :class:`~otmm_qp.robots.pinocchio_arm.PinocchioArm`; a position
task has ``ω = 0`` and no orientation cost). The peer's joint step ``Δq`` toward that target
gives the joint velocity ``q̇ = Δq/dt``.

Which rows of ``(v, ω)`` the task commands comes from the robot's
:class:`~otmm_qp.robots.peer_description.PeerDescription` (asked once, in :meth:`PeerBackend.bind`)
and its ``task_kind``, never from the robot's class.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping, Sequence
from numbers import Real
from typing import ClassVar, NamedTuple

import numpy as np
import pinocchio as pin

from otmm_qp.backends.backend import Backend, damping_weight
from otmm_qp.exceptions import ParameterError, PeerUnavailable, SolverNotFound
from otmm_qp.limits import (
    LimitSet,
    LimitSpec,
    PositionLimit,
    PredictedPositionLimit,
    VelocityLimit,
    make_limits,
)
from otmm_qp.limits.options import LIMITS, removed_limit_keys
from otmm_qp.limits.predicted_position_limit import FROM_PLANT
from otmm_qp.plants.declaration import PlantDeclaration
from otmm_qp.robots.peer_description import PeerDescription
from otmm_qp.robots.peer_models import describe
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.robots.velocity_task import task_rows
from otmm_qp.state import KinematicState
from otmm_qp.validation import Boolean, Constraints, InstanceOf, Interval, check_params

#: The peers' Tikhonov weight μ when neither ``damping`` nor ``regularization`` is given.
DEFAULT_REGULARIZATION = 1e-12

#: ``pip install`` hint shown when a peer is missing.
INSTALL_HINTS: dict[str, str] = {
    "pink": 'pip install "otmm-qp[peers]"  (or: pip install pin-pink)',
    "mink": 'pip install "otmm-qp[peers]"  (or: pip install mink mujoco)',
    "drake": 'pip install "otmm-qp[peers]"  (or: pip install drake)',
    "oink": 'pip install "otmm-qp[peers]"  (or: pip install roboplan-oink)',
}


def require(peer: str, modules: Sequence[str]) -> None:
    """Import ``modules`` or raise :class:`PeerUnavailable` with the install hint.

    Raises:
        PeerUnavailable: One of the modules cannot be imported.
    """
    for module in modules:
        try:
            importlib.import_module(module)
        except ImportError as error:
            raise PeerUnavailable(
                peer, f"{INSTALL_HINTS[peer]} (import {module!r} failed: {error})"
            ) from error


class PeerLimits(NamedTuple):
    """A backend's limits in the terms every peer takes (pink, mink, Drake).

    Attributes:
        speed: Joint speed limits [rad/s], shape ``(nv,)`` (inf: unlimited), of the
            ``velocity`` limits (their intersection); None when the backend has no limits.
        gain: Position gain ``g ∈ (0, 1]`` of the ``position`` limits (the smallest, which is
            their intersection), or None when there is none.
        margin: Distance [rad] kept from each position limit (the largest total margin of a
            ``predicted_position`` limit: ``margin`` + k σ + quantum/2), written into the
            peer's model limits; 0 for ``position``.
    """

    speed: FloatArray | None
    gain: float | None
    margin: float = 0.0


#: The limit types the peers map onto their own limits (``predicted_position``: its gain and
#: its margin; see :func:`peer_limit_set` for what it cannot map).
PEER_LIMITS = (VelocityLimit, PositionLimit, PredictedPositionLimit)

#: ``predicted_position`` parameters no peer can express: the peers bound the step around the
#: configuration they see, with no model of the commands in flight, braking, ramp or rate limit.
UNMAPPED = ("delay", "tau", "deceleration", "ramp_start", "rate_limit")

_NON_NEGATIVE = Interval(Real, 0, None, closed="left")
#: The declared constraint of the peers' ``limits``.
PEER_LIMIT_CONSTRAINTS: Constraints = {"limits": [Boolean(), LIMITS, None]}
#: The older key the peers took, refused with the ``limits`` list to write instead.
PEER_REMOVED = removed_limit_keys("limit_gain")
#: The declared constraints of the QP-based peers (pink, mink).
QP_PEER_CONSTRAINTS: Constraints = {
    "solver": InstanceOf((str,), "an installed qpsolvers backend name"),
    "damping": [_NON_NEGATIVE, None],
    "regularization": [_NON_NEGATIVE, None],
    "lm_damping": _NON_NEGATIVE,
    **PEER_LIMIT_CONSTRAINTS,
}


def peer_limit_set(limits: bool | Sequence[LimitSpec] | None, peer: str) -> LimitSet:
    """The :class:`~otmm_qp.limits.LimitSet` of a peer adapter's ``limits`` option.

    ``limits`` is the list form of :mod:`otmm_qp.limits.options`, or ``true`` / None (the
    default ``velocity`` + ``{type: position, gain: 0.5}``), or ``false`` (no limits).

    Raises:
        ParameterError: A limit the peer has no counterpart of (anything but ``velocity`` and
            ``position``), or an invalid entry.
    """
    if limits is False:
        return LimitSet((), ())
    entries = None if limits is None or limits is True else limits
    made = make_limits(entries)
    for limit in made.all:
        if type(limit) not in PEER_LIMITS:
            raise ParameterError(
                "limits",
                f"{peer} has no counterpart of limit {limit.name!r}; allowed: velocity, "
                "position, predicted_position",
            )
        if isinstance(limit, PredictedPositionLimit):
            for key in UNMAPPED:
                value = getattr(limit, key)
                if value not in (None, FROM_PLANT):
                    raise ParameterError(
                        f"limits.{key}",
                        f"{peer} has no counterpart of predicted_position's {key} (it bounds "
                        "the step around the configuration it sees); allowed: gain, margin, "
                        "noise, quantum, noise_bound",
                    )
    return made


def peer_limits(limit_set: LimitSet, robot: Robot, dt: float) -> PeerLimits:
    """Bind ``limit_set`` and reduce it to the :class:`PeerLimits` a peer takes."""
    if not limit_set.boxes:
        return PeerLimits(None, None)
    speed = np.full(robot.nv, np.inf)
    gain: float | None = None
    margin = 0.0
    for limit in limit_set.boxes:
        limit.bind(robot, dt)
        if isinstance(limit, VelocityLimit):
            speed = np.minimum(speed, limit.speed)
        elif isinstance(limit, PositionLimit):
            gain = limit.gain if gain is None else min(gain, limit.gain)
        if isinstance(limit, PredictedPositionLimit):
            margin = max(margin, limit.total_margin)
    return PeerLimits(speed, gain, margin)


def shrunk_limits(robot: Robot, margin: float) -> tuple[FloatArray, FloatArray]:
    """The robot's position limits ``(lower + m, upper − m)``, shapes ``(nv,)`` (±inf kept)."""
    lower, upper = robot.position_limits
    return np.asarray(lower, dtype=float) + margin, np.asarray(upper, dtype=float) - margin


class PeerBackend(Backend):
    """A backend that delegates each step to a third-party IK library.

    Subclasses import their library in ``__init__`` (via :func:`require`, so a missing peer
    becomes :class:`PeerUnavailable` before the run starts), build the peer's model in
    :meth:`bind` (after ``super().bind``, from :attr:`description`) and implement
    :meth:`solve`.

    Attributes:
        description: The robot's checked peer description (set by :meth:`bind`).
        task_rows: Rows of the frame twist ``(v, ω)`` the task commands, shape ``(n,)``.
    """

    #: Peer library name (``pink``, ``mink``, ``drake``).
    peer: str = "peer"

    def bind(self, robot: Robot, dt: float) -> None:
        """Attach the robot and ask it, once, for its :class:`PeerDescription`.

        Raises:
            RobotLoadError: The robot cannot describe itself to a peer, or its description
                does not match it (see :func:`~otmm_qp.robots.peer_models.describe`).
        """
        super().bind(robot, dt)
        self.description: PeerDescription = describe(robot)
        self.task_rows: np.ndarray = task_rows(self.description.planar, robot.task_kind)

    @staticmethod
    def physical_velocity(state: KinematicState, xdot: FloatArray) -> FloatArray:
        r"""Un-weighted task velocity :math:`\dot x = W^{-1}\dot x_w`, shape ``(n,)``."""
        return np.asarray(xdot, dtype=float) / state.weight

    def spatial_velocity(self, xdot: FloatArray) -> tuple[FloatArray, FloatArray]:
        """World-aligned ``(v [m/s], ω [rad/s])``, shapes ``(3,)``, of a task velocity ``(n,)``.

        Planar: ``v = (ẋ, ẏ, 0)``; position tasks: ``ω = 0``; pose tasks: ``(v, ω)``.
        """
        twist = np.zeros(6)
        twist[self.task_rows] = xdot
        return twist[:3], twist[3:]

    @staticmethod
    def advanced_pose(
        pose: FloatArray, linear: FloatArray, angular: FloatArray, dt: float
    ) -> FloatArray:
        r"""Target ``T*`` (4, 4): :math:`p^* = p + v\,dt,\ R^* = \exp(\omega\,dt) R`."""
        target = np.array(pose, dtype=float)
        target[:3, 3] += linear * dt
        target[:3, :3] = pin.exp3(angular * dt) @ target[:3, :3]
        return target

    def declare_plant(self, declaration: PlantDeclaration) -> None:
        """Hand the plant's declaration to the limits (only their margin reaches the peer)."""
        for limit in self.limit_set.boxes:
            limit.declare_plant(declaration)

    def configure_limits(self, limits: bool | Sequence[LimitSpec] | None) -> None:
        """Validate and store the limits (:func:`peer_limit_set`); read back at :meth:`bind`.

        Raises:
            ParameterError: See :func:`peer_limit_set`.
        """
        self.limit_set = peer_limit_set(limits, self.peer)
        self.enforces_limits = bool(self.limit_set.boxes)

    def orientation_weight(self) -> float:
        """1 when the task commands the angular velocity (pose tasks), else 0."""
        return 1.0 if bool(np.any(self.task_rows >= 3)) else 0.0


class QpPeerBackend(PeerBackend):
    """A peer that solves a QP through qpsolvers (pink, mink): the settings they share.

    Subclasses name their library (:attr:`peer`) and the modules it needs (:attr:`modules`),
    and build the peer's model in :meth:`bind`.

    Args:
        solver: An installed qpsolvers backend, e.g. ``daqp``, ``proxqp``, ``osqp``.
        damping: λ ≥ 0 [task units]: the library's Tikhonov weight is μ = λ²
            (:func:`damping_weight`).
        regularization: μ ≥ 0 itself [cost]/[rad²] instead of ``damping``; 10⁻¹² when
            neither is given.
        lm_damping: The library's Levenberg–Marquardt damping ≥ 0 of the frame task.
        limits: The ``limits`` option (:func:`peer_limit_set`).

    Raises:
        PeerUnavailable: A module of :attr:`modules` is not installed.
        SolverNotFound: ``solver`` is not an installed qpsolvers backend.
        ParameterError: A damping is negative or not finite, or a limit is invalid.
    """

    #: Modules the peer library needs (checked by :func:`require` before anything else).
    modules: ClassVar[tuple[str, ...]] = ()
    parameter_constraints: ClassVar[Constraints] = QP_PEER_CONSTRAINTS
    removed_parameters: ClassVar[Mapping[str, str]] = PEER_REMOVED

    def __init__(
        self,
        solver: str = "daqp",
        damping: float | None = None,
        regularization: float | None = None,
        lm_damping: float = 0.0,
        limits: bool | Sequence[LimitSpec] | None = None,
    ) -> None:
        check_params(self, locals())
        require(self.peer, list(self.modules))
        import qpsolvers

        if solver not in qpsolvers.available_solvers:
            raise SolverNotFound(solver, qpsolvers.available_solvers)
        self.solver = solver
        self.regularization = damping_weight(damping, regularization, DEFAULT_REGULARIZATION)
        self.lm_damping = float(lm_damping)
        self.configure_limits(limits)
