"""A controller = zero or more task filters followed by one backend."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from otmm_qp.backends.backend import Backend, BackendOutput
from otmm_qp.exceptions import DimensionError, ParameterError
from otmm_qp.filters.task_filter import FilterReport, TaskFilter
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.status import (
    DIVERGENCE_SPEED,
    SpeedWork,
    Status,
    classify,
    quiet_speed_squared,
    speed_limit_thresholds,
)
from otmm_qp.trajectories.trajectory import Trajectory

if TYPE_CHECKING:
    from otmm_qp.plants.declaration import PlantDeclaration


#: The dtype ``np.asarray(x, dtype=float)`` gives.
_FLOAT = np.dtype(float)


class ControllerOutput(NamedTuple):
    """One control step.

    Attributes:
        qdot: Joint velocity [rad/s], shape ``(nv,)``, always finite.
        xdot_filtered: Filtered task velocity in physical units, shape ``(n,)``.
        reports: One :class:`FilterReport` per filter.
        backend: What the backend returned (status ``nonfinite`` if the guard replaced q̇).
    """

    qdot: FloatArray
    xdot_filtered: FloatArray
    reports: tuple[FilterReport, ...]
    backend: BackendOutput


class Controller:
    r"""Filters then backend, in the weighted task space of the state.

    .. math:: \dot x_w = W\dot x,\quad \dot x_m = F_k \circ\dots\circ F_1(\dot x_w),
              \quad \dot q = B(J_w, \dot x_m)

    Args:
        name: Label used in results.
        filters: Task filters applied in order.
        backend: The inversion backend.
        divergence_speed: Joint speed [rad/s] above which a solved step is reported
            ``diverging`` whatever the backend (see :mod:`otmm_qp.status`), > 0.
        filter_names: The names the filters were registered under, one per filter, kept
            beside the objects (the results' ``filters`` column); default each filter's
            class-level ``name``.
        backend_name: The name the backend was registered under (the results' ``backend``
            column); default its class-level ``name``.

    Raises:
        ParameterError: ``divergence_speed`` not > 0, ``filter_names`` not one per filter, or
            filters in front of a backend that reads a preview (it never reads the command).
    """

    def __init__(
        self,
        name: str,
        filters: Sequence[TaskFilter],
        backend: Backend,
        divergence_speed: float = DIVERGENCE_SPEED,
        *,
        filter_names: Sequence[str] | None = None,
        backend_name: str | None = None,
    ) -> None:
        try:
            speed = float(divergence_speed)
        except (TypeError, ValueError):
            speed = math.nan
        if not speed > 0.0:  # also refuses NaN; inf turns the check off
            raise ParameterError(
                "divergence_speed", f"must be a number > 0 [rad/s], got {divergence_speed!r:.40}"
            )
        self.name = name
        self.filters = tuple(filters)
        self.backend = backend
        if self.filters and backend.preview_horizon is not None:
            raise ParameterError(
                "filters",
                f"backend {backend.name!r} reads the desired path ahead, not the filtered "
                "command, so filters would do nothing; remove them (or use its causal "
                "counterpart, e.g. preview_causal)",
            )
        names = tuple(f.name for f in self.filters) if filter_names is None else tuple(filter_names)
        if len(names) != len(self.filters):
            raise ParameterError(
                "filter_names",
                f"must name each of the {len(self.filters)} filters, got {names!r:.80}",
            )
        #: Registered names of the filters, in order.
        self.filter_names: tuple[str, ...] = names
        #: Registered name of the backend.
        self.backend_name: str = backend.name if backend_name is None else backend_name
        self._divergence_speed = speed
        self._speed_thresholds: FloatArray | None = None
        # ‖q̇‖² below this: no speed rule can apply (set per run by bind).
        self._quiet_squared = speed * speed  # inf stays inf: the check is then off
        self._speed_work: SpeedWork | None = None

    @property
    def divergence_speed(self) -> float:
        """Joint speed [rad/s] above which a solved step is reported ``diverging``."""
        return self._divergence_speed

    def bind(self, robot: Robot, dt: float, trajectory: Trajectory | None = None) -> None:
        """Prepare for a run on ``robot`` with period ``dt`` [s] along ``trajectory``.

        The trajectory is handed to the backend (:meth:`Backend.attach`); a preview backend
        refuses one that cannot give its horizon, before any step.

        Raises:
            PreviewUnavailable: The backend's preview exceeds the trajectory's lookahead.
        """
        for task_filter in self.filters:
            task_filter.bind(robot, dt)
        self.backend.bind(robot, dt)
        if trajectory is not None:
            self.backend.attach(trajectory)
        limits = np.asarray(robot.velocity_limits, dtype=float)
        check = not self.backend.enforces_limits and bool(np.isfinite(limits).any())
        self._speed_thresholds = speed_limit_thresholds(limits) if check else None
        self._quiet_squared = quiet_speed_squared(self._speed_thresholds, self._divergence_speed)
        self._speed_work = SpeedWork(robot.nv)
        self.reset()

    def declare_plant(self, declaration: PlantDeclaration) -> None:
        """Hand what the run's plant declares about itself to the backend (before :meth:`bind`)."""
        self.backend.declare_plant(declaration)

    def reset(self) -> None:
        """Reset filters and backend state."""
        for task_filter in self.filters:
            task_filter.reset()
        self.backend.reset()

    def step(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> ControllerOutput:
        """Compute ``q̇`` for the physical command ``xdot`` (n,) at ``state``.

        The step's status is classified once, here (:func:`otmm_qp.status.classify`):
        non-finite backend output is replaced by zero joint speed with status ``nonfinite``,
        so NaN/inf never leave a step; an ``ok`` step of a backend that does not enforce
        limits and exceeds the robot's speed limits is ``saturated``; a solved step faster
        than ``divergence_speed`` is ``diverging``.

        Raises:
            DimensionError: ``xdot`` is not of shape ``(n,)`` or ``qdot_prev`` not ``(nv,)``.
        """
        # Float64 ndarrays (the common case) as they are: the type test costs a tenth of
        # np.asarray's call, which would return them unchanged.
        if type(xdot) is not np.ndarray or xdot.dtype != _FLOAT:
            xdot = np.asarray(xdot, dtype=float)
        if type(qdot_prev) is not np.ndarray or qdot_prev.dtype != _FLOAT:
            qdot_prev = np.asarray(qdot_prev, dtype=float)
        n, nv = state.jacobian.shape
        if xdot.shape != (n,) or qdot_prev.shape != (nv,):
            wrong_xdot = xdot.shape != (n,)
            raise DimensionError(
                "xdot" if wrong_xdot else "qdot_prev",
                (n,) if wrong_xdot else (nv,),
                xdot.shape if wrong_xdot else qdot_prev.shape,
            )
        unit = state.task_jacobian is state.jacobian  # no task weight: skip the scaling
        weighted = xdot if unit else state.weight * xdot
        reports: tuple[FilterReport, ...] = ()
        if self.filters:
            collected = []
            for task_filter in self.filters:
                weighted, report = task_filter.apply(state, weighted)
                collected.append(report)
            reports = tuple(collected)
        result = self.backend.solve(state, weighted, qdot_prev)
        qdot = result.qdot
        # One dot product: NaN/inf (or |q̇| beyond 1e154) make it non-finite.
        speed_squared = float(qdot.dot(qdot))  # ndarray.dot: the least call overhead
        # Skipped when no rule can apply (quiet_speed_squared: slower than every threshold and
        # the divergence speed; NaN and inf fail the < test).
        if not speed_squared < self._quiet_squared:
            status = classify(
                result.status,
                qdot,
                speed_squared,
                self._speed_thresholds,
                self._divergence_speed,
                self._speed_work if self._speed_work is not None else SpeedWork(nv),
            )
            if status is Status.NONFINITE:
                qdot = np.zeros(nv)
            if status is not result.status or qdot is not result.qdot:
                result = (
                    BackendOutput(qdot, status, result.damping, result.scale, result.details)
                    if type(result) is BackendOutput  # a third of _replace's cost
                    else result._replace(qdot=qdot, status=status)
                )
        filtered = weighted if unit else weighted / state.weight
        # tuple.__new__: the NamedTuple without its Python-level __new__ (a third cheaper).
        return tuple.__new__(ControllerOutput, (qdot, filtered, reports, result))
