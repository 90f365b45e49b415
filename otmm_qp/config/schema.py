"""Pydantic schema of YAML experiment files.

A file holds shared defaults and a list of experiments::

    name: paper
    dt: 0.02                       # control period [s]
    loop_modes: [feedforward, clik, newton]
    clik_gain: 10.0                # [1/s]
    metrics: {sigma_s: 0.05, window: 1.0, blow_up_speed: 100.0}
    claims: paper                  # optional claim set evaluated after the runs
    experiments:
      - name: E1
        robot: {type: planar, link_lengths: [1.0, 0.8]}
        q0: [0.927, -2.5]          # joint coordinates [rad]
        trajectory: {type: circle, centre: [1.2, 0.0], radius: 0.6, period: 10.0}
        duration: 10.0             # [s], optional (trajectory duration)
        task_weight: [1.0, 1.0]    # optional diagonal W
        plant: [{type: lag, tau: 0.02}, {type: delay, steps: 1}]   # optional, default ideal
        controllers:
          - name: OTMM-linear
            filters: [{type: otmm, sigma_s: 0.05, p: linear}]
            backend: {type: pinv}
            conditioning: [{type: speed_scale}]                  # optional, default none

Plugin blocks (``robot``, ``trajectory``, ``filters[*]``, ``backend``) take ``type`` (a
registered name) plus that plugin's own parameters, checked against its constructor.
Every other key is fixed: an unknown key is an error naming its path.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator, model_validator

from otmm_qp.config.base import PluginConfig, Strict, TaskWeight
from otmm_qp.config.loop import LoopSettings
from otmm_qp.paper import SIGMA_S
from otmm_qp.paths import RESERVED_NAMES, safe_name
from otmm_qp.simulation.loop_modes import LoopMode

__all__ = [
    "ControllerConfig",
    "ExperimentConfig",
    "LoopMode",
    "MetricsConfig",
    "PluginConfig",
    "SuiteConfig",
    "check_file_name",
]


def check_file_name(kind: str, name: str) -> str:
    """Refuse a name whose file-name slug is a reserved output stem (summary, report...)."""
    stem = safe_name(name).split(".", 1)[0].lower()
    if stem in RESERVED_NAMES:
        raise ValueError(
            f"{kind} name {name[:80]!r} would clash with the output file {stem!r}; "
            f"reserved: {', '.join(RESERVED_NAMES)}"
        )
    return name


class MetricsConfig(Strict):
    """Metric parameters: σ_S for counting, window width [s], blow-up speed [rad/s]."""

    sigma_s: float = Field(SIGMA_S, gt=0.0)
    window: float = Field(1.0, gt=0.0)
    blow_up_speed: float = Field(100.0, gt=0.0)


class PresetConfig(Strict):
    """``{preset: NAME}``: the stages of a plant preset (:mod:`otmm_qp.plants.presets`).

    ``lookahead`` [s]: servoj's lookahead time of a UR preset (its lag τ; None: 0.03).
    """

    preset: str = Field(min_length=1)
    lookahead: float | None = None


#: A plant: one stage ``{type: lag, tau: 0.02}``, a preset ``{preset: franka_fci}``, or a list
#: of them applied in order (``otmm_qp.plants``).
PlantConfig = PresetConfig | PluginConfig | list[PresetConfig | PluginConfig]


class ControllerConfig(Strict):
    """A named controller: filters (applied in order) then one backend.

    ``conditioning`` (command stages after the backend, ``otmm_qp.conditioning``) and
    ``plant`` (overriding the experiment's) are optional loop options of this controller.
    """

    name: str = Field(min_length=1)
    filters: list[PluginConfig] = Field(default_factory=list)
    backend: PluginConfig
    conditioning: list[PluginConfig] = Field(default_factory=list)
    plant: PlantConfig | None = None


class ExperimentConfig(Strict):
    """One robot, start, trajectory and the controllers compared on it."""

    name: str = Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_+-][A-Za-z0-9_.+-]*$")
    description: str = ""
    robot: PluginConfig
    q0: list[float]
    trajectory: PluginConfig
    controllers: list[ControllerConfig] = Field(min_length=1)
    duration: float | None = Field(None, gt=0.0)
    dt: float | None = Field(None, gt=0.0)
    loop_modes: list[LoopMode] | None = Field(None, min_length=1)
    clik_gain: float | None = Field(None, ge=0.0)
    task_weight: TaskWeight = None
    plant: PlantConfig | None = None
    #: The trajectory leaves the workspace on purpose (a study's beyond-reach task): the
    #: runner's trajectory check (``check_reachable``) is skipped, as for study episodes.
    out_of_reach: bool = False

    @field_validator("name")
    @classmethod
    def _file_name(cls, value: str) -> str:
        return check_file_name("experiment", value)

    @field_validator("controllers")
    @classmethod
    def _unique_controllers(cls, value: list[ControllerConfig]) -> list[ControllerConfig]:
        names = [c.name for c in value]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ValueError(f"controller names must be unique; repeated: {', '.join(duplicates)}")
        return value


class SuiteConfig(LoopSettings):
    """A YAML run file: shared loop settings (``dt`` defaults to 0.02 s) and the experiments."""

    name: str = Field("experiments", min_length=1)
    description: str = ""
    metrics: MetricsConfig = MetricsConfig()  # frozen, so a shared default is safe
    claims: Literal["paper"] | None = None
    plant: PlantConfig | None = None
    experiments: list[ExperimentConfig] = Field(min_length=1)

    @model_validator(mode="after")
    def _unique_experiments(self) -> SuiteConfig:
        names = [safe_name(e.name).lower() for e in self.experiments]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ValueError(f"experiment names must be unique; repeated: {', '.join(duplicates)}")
        return self
