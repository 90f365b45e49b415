"""Pydantic schema of YAML study files (same style as :mod:`otmm_qp.config.schema`).

A study runs every controller on every task drawn by its generators, per robot::

    name: planar
    seed: 1
    dt: 0.02                          # control period [s]
    loop_modes: [clik]
    clik_gain: 10.0                   # [1/s]
    duration: {extra: 0.5}            # episode time = trajectory duration + extra [s]
    chunk_size: 8                     # tasks per unit of work sent to a worker
    metrics: {sigma_s: 0.05, window: 1.0, blow_up_speed: 100.0}
    success: {max_position_error: 0.01, max_joint_speed: 10.0}
    robots:
      - name: planar3
        robot: {type: planar, link_lengths: [1.0, 0.8, 0.5]}
    generators:
      - {type: near_singular, count: 50, distance: [0.0, 0.05]}
    controllers:
      - name: otmm
        filters: [{type: otmm}]
        backend: {type: pinv}
        grid: {sigma_s: [0.01, 0.05], p: [linear, cbrt]}   # 4 controllers

``grid`` keys are a parameter name (set in the one block of the controller that accepts
it) or an explicit ``backend.NAME`` / ``filters.INDEX.NAME``.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from otmm_qp.config.schema import MetricsConfig, PluginSpec
from otmm_qp.simulation.episode import DEFAULT_MAX_STEPS
from otmm_qp.simulation.loop_modes import LoopMode


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class StudyRobot(_Strict):
    """A robot of the study: a label, the robot plugin and an optional task weight."""

    name: str = Field(min_length=1, pattern=r"^[A-Za-z0-9_.+-]+$")
    robot: PluginSpec
    task_weight: list[float] | None = None

    @field_validator("task_weight")
    @classmethod
    def _positive(cls, value: list[float] | None) -> list[float] | None:
        if value is not None and any(not w > 0.0 for w in value):
            raise ValueError("every task weight must be > 0")
        return value


class GeneratorSpec(BaseModel):
    """``{type: NAME, count: N, **params}``: a registered task generator, N tasks per robot."""

    model_config = ConfigDict(extra="allow", frozen=True)

    type: str = Field(min_length=1)
    count: int = Field(gt=0)

    @property
    def params(self) -> dict[str, Any]:
        """Generator parameters (everything but ``type`` and ``count``)."""
        return dict(self.model_extra or {})


class StudyController(_Strict):
    """A controller, or a family of controllers when ``grid`` is given."""

    name: str = Field(min_length=1)
    filters: list[PluginSpec] = Field(default_factory=list)
    backend: PluginSpec
    grid: dict[str, list[Any]] = Field(default_factory=dict)


class DurationRule(_Strict):
    """Episode duration: the task's trajectory duration plus ``extra`` [s], capped at ``max``."""

    extra: float = Field(0.5, ge=0.0)
    max: float | None = Field(None, gt=0.0)


class GracefulCriteria(_Strict):
    """What success means on a task the reference found unachievable (see ``studies/criteria.py``).

    Attributes:
        error_factor: ``f_e``: bound on ``max_error`` (and orientation) as a multiple of the
            reference's best [-].
        max_jump_factor: ``f_c``: no chatter: largest one-step change of any joint's speed as a
            fraction of its velocity limit [-].
        return_to_path: Also require ``final_error ≤ max(max_position_error,
            f_e · reference.final_error)``.
    """

    error_factor: float = Field(1.5, ge=1.0, allow_inf_nan=False)
    max_jump_factor: float = Field(0.5, gt=0.0, allow_inf_nan=False)
    return_to_path: bool = True


class SuccessCriteria(_Strict):
    """An episode succeeds when it completes and every given bound holds.

    Attributes:
        max_position_error: Bound on ``max_error`` [m] (achievable tasks).
        max_orientation_error: Bound on ``max_orientation_error`` [rad] (pose tasks).
        max_joint_speed: Absolute bound on ``max_joint_speed`` = max ‖q̇‖∞ [rad/s]; when given
            it replaces the per-joint bound ``joint_speed_factor``.
        joint_speed_factor: Per-joint bound: ``|q̇_j| ≤ factor · q̇_max,j``, the robot's own
            velocity limits [-] (used when ``max_joint_speed`` is not given).
        no_limit_violation: Require zero position-limit violations.
        no_blow_up: Require ``blow_up`` to be false.
        graceful: Criteria on tasks whose reference is not achievable.
    """

    max_position_error: float | None = Field(0.01, gt=0.0, allow_inf_nan=False)
    max_orientation_error: float | None = Field(None, gt=0.0, allow_inf_nan=False)
    max_joint_speed: float | None = Field(None, gt=0.0, allow_inf_nan=False)
    joint_speed_factor: float = Field(1.0, gt=0.0, allow_inf_nan=False)
    no_limit_violation: bool = True
    no_blow_up: bool = True
    graceful: GracefulCriteria = GracefulCriteria()


class TimeSeriesConfig(_Strict):
    """Sampled time series of the first ``tasks`` tasks per robot and generator.

    Every ``stride``-th step is kept.
    """

    tasks: int = Field(2, ge=0)
    stride: int = Field(5, gt=0)


def _default_loop_modes() -> list[LoopMode]:
    return ["clik"]


class StudyConfig(_Strict):
    """A study file."""

    name: str = Field(min_length=1, pattern=r"^[A-Za-z0-9_.+-]+$")
    description: str = ""
    seed: int = Field(0, ge=0)
    dt: float = Field(0.01, gt=0.0)
    loop_modes: list[LoopMode] = Field(default_factory=_default_loop_modes, min_length=1)
    clik_gain: float = Field(10.0, ge=0.0)
    duration: DurationRule = DurationRule()
    chunk_size: int = Field(4, gt=0)
    max_steps: int = Field(DEFAULT_MAX_STEPS, gt=0)
    metrics: MetricsConfig = MetricsConfig()
    success: SuccessCriteria = SuccessCriteria()
    time_series: TimeSeriesConfig = TimeSeriesConfig()
    robots: list[StudyRobot] = Field(min_length=1)
    generators: list[GeneratorSpec] = Field(min_length=1)
    controllers: list[StudyController] = Field(min_length=1)

    @field_validator("loop_modes")
    @classmethod
    def _unique_modes(cls, value: list[LoopMode]) -> list[LoopMode]:
        if len(set(value)) != len(value):
            raise ValueError("loop modes must be unique")
        return value

    @model_validator(mode="after")
    def _unique_robots(self) -> StudyConfig:
        names = [r.name for r in self.robots]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ValueError(f"robot names must be unique; repeated: {', '.join(duplicates)}")
        return self
