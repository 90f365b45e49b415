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

``plants`` (optional) is one more grid axis: every controller runs under each plant on the
same tasks, named ``controller@plant``::

    plants:
      - {name: ideal, plant: {type: ideal}}
      - {name: lag20-delay1, plant: [{type: lag, tau: 0.02}, {type: delay, steps: 1}]}

``grid`` keys are a parameter name (set in the one block of the controller that accepts
it) or an explicit ``backend.NAME`` / ``filters.INDEX.NAME``.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from otmm_qp.config.base import PluginConfig, Strict, TaskWeight
from otmm_qp.config.loop import LoopSettings
from otmm_qp.config.schema import ControllerConfig, MetricsConfig, PlantConfig


class StudyRobot(Strict):
    """A robot of the study: a label, the robot plugin and an optional task weight."""

    name: str = Field(min_length=1, pattern=r"^[A-Za-z0-9_.+-]+$")
    robot: PluginConfig
    task_weight: TaskWeight = None


class GeneratorSpec(BaseModel):
    """``{type: NAME, count: N, name: LABEL, **params}``: a task generator, N tasks per robot.

    ``name`` (optional) labels the entry in ``task_id`` and seeds its tasks, so two entries
    of one type (e.g. two distance ranges) give different tasks and are counted apart.
    """

    model_config = ConfigDict(extra="allow", frozen=True)

    type: str = Field(min_length=1)
    count: int = Field(gt=0)
    name: str | None = Field(None, min_length=1, pattern=r"^[A-Za-z0-9_.+#-]+$")

    @property
    def params(self) -> dict[str, Any]:
        """Generator parameters (everything but ``type``, ``count`` and ``name``)."""
        return dict(self.model_extra or {})


class StudyController(ControllerConfig):
    """A controller, or a family of controllers when ``grid`` is given."""

    grid: dict[str, list[Any]] = Field(default_factory=dict)


class StudyPlant(Strict):
    """One value of the ``plants`` axis: a label and a plant (a stage or a list of stages)."""

    name: str = Field(min_length=1, pattern=r"^[A-Za-z0-9_.+-]+$")
    plant: PlantConfig


class DurationRule(Strict):
    """Episode duration: the task's trajectory duration plus ``extra`` [s], capped at ``max``."""

    extra: float = Field(0.5, ge=0.0)
    max: float | None = Field(None, gt=0.0)


class GracefulCriteria(Strict):
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


class SuccessCriteria(Strict):
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


class TimeSeriesConfig(Strict):
    """Sampled time series of the first ``tasks`` tasks per robot and generator.

    Every ``stride``-th step is kept.
    """

    tasks: int = Field(2, ge=0)
    stride: int = Field(5, gt=0)


class ReferenceConfig(Strict):
    """The offline-optimal reference computed once per task (an ``oracle`` row).

    Attributes:
        enabled: Compute it.
        time_budget: Wall-clock budget per task [s] (a safety net: the iteration caps bind
            first, so results do not depend on the machine's load); the solve stops at it with
            the best
            path so far (the upper bound; ``failed`` only on a solver failure).
        speed_bound: ``criteria``: joint speeds within the robot's limits *and* the
            success criterion ``max_joint_speed`` (a certificate then means a controller could
            succeed); ``robot``: within the robot's limits only.
        iterations: Newton iterations of the least-squares phase.
        minimax_rounds: Min-max re-weighting rounds (only when a tolerance is missed).
        polish_iterations: Cap on the epigraph min-max QPs per start (it stops earlier on
            its convergence test: step and KKT residual).
        starts: Best distinct starts the min-max solve runs from (damped IK, the task's joint
            path, the least-squares path, controller paths that kept every limit).
        perturbations: Extra starts: the best path plus seeded joint noise.
    """

    enabled: bool = True
    time_budget: float = Field(60.0, gt=0.0, allow_inf_nan=False)
    speed_bound: Literal["criteria", "robot"] = "criteria"
    iterations: int = Field(6, ge=0)
    minimax_rounds: int = Field(1, ge=0)
    polish_iterations: int = Field(20, ge=0)
    starts: int = Field(1, ge=1)
    perturbations: int = Field(0, ge=0)


#: Generator parameters that set how much work one task may take (each bounded by
#: ``limits.max_generator_budget``).
GENERATOR_BUDGETS = ("attempts", "restarts", "iterations")


class PlanLimits(Strict):
    """Bounds on the size of a study, checked before anything is allocated (raise them here).

    Attributes:
        max_tasks: Tasks drawn in all: robots × Σ generator ``count``.
        max_controllers: Controllers after grid expansion (Σ over controllers of the product
            of the grid axis lengths).
        max_episodes: Episodes: tasks × (controllers × loop modes + 1 reference when
            ``reference.enabled``).
        max_generator_budget: Largest ``attempts``, ``restarts`` or ``iterations`` of a
            generator.
    """

    max_tasks: int = Field(100_000, gt=0)
    max_controllers: int = Field(1_000, gt=0)
    max_episodes: int = Field(1_000_000, gt=0)
    max_generator_budget: int = Field(10_000, gt=0)


class DecideRule(Strict):
    """``decide: {budget_tasks: N, batch: M}``: run batches of ``M`` until decided or ``N``.

    Attributes:
        budget_tasks: Most tasks per robot (the generators' counts are the split's weights).
        batch: Tasks per robot added by each batch (``≤ budget_tasks``).
    """

    budget_tasks: int = Field(gt=0, le=1_000_000)
    batch: int = Field(gt=0, le=1_000_000)


class StudyConfig(LoopSettings):
    """A study file: loop settings (``dt`` defaults to 0.01 s), robots, tasks, controllers."""

    name: str = Field(min_length=1, pattern=r"^[A-Za-z0-9_.+-]+$")
    description: str = ""
    seed: int = Field(0, ge=0)
    dt: float = Field(0.01, gt=0.0)
    duration: DurationRule = DurationRule()
    chunk_size: int = Field(4, gt=0)
    metrics: MetricsConfig = MetricsConfig()
    success: SuccessCriteria = SuccessCriteria()
    time_series: TimeSeriesConfig = TimeSeriesConfig()
    reference: ReferenceConfig = ReferenceConfig()
    limits: PlanLimits = PlanLimits()
    robots: list[StudyRobot] = Field(min_length=1)
    generators: list[GeneratorSpec] = Field(min_length=1)
    controllers: list[StudyController] = Field(min_length=1)
    plants: list[StudyPlant] | None = Field(None, min_length=1)
    decide: DecideRule | None = None  # batches until decided (studies/decide.py)

    @field_validator("plants")
    @classmethod
    def _unique_plants(cls, value: list[StudyPlant] | None) -> list[StudyPlant] | None:
        names = [p.name for p in value or []]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ValueError(f"plant names must be unique; repeated: {', '.join(duplicates)}")
        return value

    @model_validator(mode="after")
    def _unique_robots(self) -> StudyConfig:
        names = [r.name for r in self.robots]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ValueError(f"robot names must be unique; repeated: {', '.join(duplicates)}")
        return self
