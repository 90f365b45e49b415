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
        controllers:
          - name: OTMM-linear
            filters: [{type: otmm, sigma_s: 0.05, p: linear}]
            backend: {type: pinv}

Plugin blocks (``robot``, ``trajectory``, ``filters[*]``, ``backend``) take ``type`` (a
registered name) plus that plugin's own parameters, checked against its constructor.
Every other key is fixed: an unknown key is an error naming its path.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from otmm_qp.output.paths import RESERVED_NAMES, safe_name
from otmm_qp.simulation.episode import DEFAULT_MAX_STEPS
from otmm_qp.simulation.loop_modes import LoopMode


class _Strict(BaseModel):
    # NaN and ±inf are refused in every float field (dt: .inf, clik_gain: .inf, q0: [.nan]).
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


def check_file_name(kind: str, name: str) -> str:
    """Refuse a name whose file-name slug is a reserved output stem (summary, report...)."""
    stem = safe_name(name).split(".", 1)[0].lower()
    if stem in RESERVED_NAMES:
        raise ValueError(
            f"{kind} name {name[:80]!r} would clash with the output file {stem!r}; "
            f"reserved: {', '.join(RESERVED_NAMES)}"
        )
    return name


class PluginSpec(BaseModel):
    """``{type: NAME, **params}``: a registered plugin and its parameters."""

    model_config = ConfigDict(extra="allow", frozen=True)

    type: str = Field(min_length=1)

    @property
    def params(self) -> dict[str, Any]:
        """Parameters other than ``type``."""
        return dict(self.model_extra or {})


class MetricsConfig(_Strict):
    """Metric parameters: σ_S for counting, window width [s], blow-up speed [rad/s]."""

    sigma_s: float = Field(0.05, gt=0.0)
    window: float = Field(1.0, gt=0.0)
    blow_up_speed: float = Field(100.0, gt=0.0)


class ControllerConfig(_Strict):
    """A named controller: filters (applied in order) then one backend."""

    name: str = Field(min_length=1)
    filters: list[PluginSpec] = Field(default_factory=list)
    backend: PluginSpec


class ExperimentConfig(_Strict):
    """One robot, start, trajectory and the controllers compared on it."""

    name: str = Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_+-][A-Za-z0-9_.+-]*$")
    description: str = ""
    robot: PluginSpec
    q0: list[float]
    trajectory: PluginSpec
    controllers: list[ControllerConfig] = Field(min_length=1)
    duration: float | None = Field(None, gt=0.0)
    dt: float | None = Field(None, gt=0.0)
    loop_modes: list[LoopMode] | None = Field(None, min_length=1)
    clik_gain: float | None = Field(None, ge=0.0)
    task_weight: list[float] | None = None
    #: The trajectory leaves the workspace on purpose (a study's beyond-reach task): the
    #: runner's workspace check is skipped (its shape and finiteness checks still apply).
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

    @field_validator("task_weight")
    @classmethod
    def _positive_weight(cls, value: list[float] | None) -> list[float] | None:
        if value is not None and any(not w > 0.0 for w in value):
            raise ValueError("every task weight must be > 0")
        return value


def _default_loop_modes() -> list[LoopMode]:
    return ["clik"]


class SuiteConfig(_Strict):
    """A YAML file: shared defaults and the experiments."""

    name: str = Field("experiments", min_length=1)
    description: str = ""
    dt: float = Field(0.02, gt=0.0)
    loop_modes: list[LoopMode] = Field(default_factory=_default_loop_modes, min_length=1)
    clik_gain: float = Field(10.0, ge=0.0)
    metrics: MetricsConfig = MetricsConfig()  # frozen, so a shared default is safe
    claims: Literal["paper"] | None = None
    max_steps: int = Field(DEFAULT_MAX_STEPS, gt=0)
    experiments: list[ExperimentConfig] = Field(min_length=1)

    @model_validator(mode="after")
    def _unique_experiments(self) -> SuiteConfig:
        names = [safe_name(e.name).lower() for e in self.experiments]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ValueError(f"experiment names must be unique; repeated: {', '.join(duplicates)}")
        return self
