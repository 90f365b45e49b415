"""Plants and conditioning of a run from its config: built fresh per run, checked before compute.

A run's plant comes from the controller's own ``plant``, else the experiment's, else the
suite's (default: ideal); its conditioning from the controller's ``conditioning`` list.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from otmm_qp.conditioning.pipeline import Conditioning, build_conditioning
from otmm_qp.config.schema import ControllerConfig, PresetConfig
from otmm_qp.exceptions import ConfigError, DimensionError, OtmmError
from otmm_qp.plants.chain import PlantChain, build_plant
from otmm_qp.plants.declaration import PlantDeclaration
from otmm_qp.plants.presets import LOOKAHEAD_KEY, PRESET_KEY
from otmm_qp.robots.robot import FloatArray, Robot

__all__ = [
    "build_stage",
    "check_conditioning",
    "check_plant",
    "plant_declarations",
    "plant_record",
]


def build_stage(config: ControllerConfig) -> tuple[PlantChain, Conditioning]:
    """A fresh plant (the controller's own, else ideal) and conditioning for one run."""
    conditioning = [dict(s.params, type=s.type) for s in config.conditioning]
    return build_plant(plant_record(config.plant)), build_conditioning(conditioning)


def plant_record(spec: Any) -> Any:
    """A plant config (a :class:`PluginConfig`, a preset, a list of them, or None) as data."""
    if spec is None:
        return None
    if isinstance(spec, list):
        return [plant_record(s) for s in spec]
    if isinstance(spec, PresetConfig):
        if spec.lookahead is not None:
            return {PRESET_KEY: spec.preset, LOOKAHEAD_KEY: spec.lookahead}
        return {PRESET_KEY: spec.preset}
    return dict(spec.params, type=spec.type)


def check_plant(
    plant: Any, robot: Robot, q0: FloatArray, dt: float, field: str,
    budget: tuple[int, int] | None = None,
) -> None:  # fmt: skip
    """Build and reset a plant once on ``robot`` at ``q0``, so bad input fails before compute.

    Args:
        plant: The plant's config record.
        robot: The arm.
        q0: Start configuration (nq,).
        dt: Control period [s].
        field: The plant's config path.
        budget: ``(steps, max_steps)`` of the run: a stage stepping ``substeps`` times per
            control period (MuJoCo) counts ``steps × substeps`` against ``max_steps``.

    Raises:
        ConfigError: Naming ``field`` (the plant's config path) and what is wrong: an
            out-of-range parameter, a MuJoCo model that does not compile, a URDF without
            inertias or effort limits, MuJoCo not installed, more plant steps than
            ``max_steps``.
    """
    try:
        chain = build_plant(plant, field)
        chain.reset(robot, q0, dt)
        if budget is not None:
            _check_substeps(chain, *budget, field)
    except ConfigError as error:
        preset = _preset_name(plant)
        if preset is not None and error.field.endswith("effort_limit"):
            joint = error.message.split(" has no", 1)[0]
            raise ConfigError(
                f"{field}.preset",
                f"{preset!r} needs a positive URDF effort for every joint (its MuJoCo body "
                f"applies them): {joint} has none; list the preset's stages (docs/plants.md) "
                "with the mujoco stage's effort_limit instead",
            ) from None
        if error.field.startswith(field):
            raise
        raise ConfigError(f"{field}.{error.field}".rstrip("."), error.message) from None
    except DimensionError as error:
        raise ConfigError(field, str(error)) from None


def _check_substeps(chain: PlantChain, steps: int, max_steps: int, field: str) -> None:
    """Refuse ``steps × substeps`` (the physics steps of a run) above ``max_steps``."""
    substeps = max(int(getattr(stage, "substeps", 1)) for stage in chain.stages)
    if steps * substeps > max_steps:
        raise ConfigError(
            field,
            f"{steps} control steps × {substeps} plant steps per period = "
            f"{steps * substeps:.3g} exceeds max_steps = {max_steps}; raise the plant's "
            "timestep, shorten duration, or raise max_steps explicitly",
        )


def _preset_name(plant: Any) -> str | None:
    """The preset a plant config names (alone or in its list), or None."""
    blocks = plant if isinstance(plant, list) else [plant]
    for block in blocks:
        if isinstance(block, dict) and PRESET_KEY in block:
            return str(block[PRESET_KEY])
    return None


def check_conditioning(
    conditioning: dict[str, list[dict[str, Any]]], robot: Robot, dt: float, field: str
) -> None:
    """Build and reset every controller's conditioning stages once (see :func:`check_plant`).

    Raises:
        ConfigError: Naming the controller's ``conditioning`` stage and what is wrong.
    """
    for name, stages in conditioning.items():
        where = f"{field}.controllers ({name}).conditioning"
        try:
            build_conditioning(stages, where).reset(robot, dt)
        except ConfigError as error:
            if error.field.startswith(where):
                raise
            raise ConfigError(f"{where}.{error.field}".rstrip("."), error.message) from None
        except DimensionError as error:
            raise ConfigError(where, str(error)) from None


def plant_declarations(records: Iterable[Any], dt: float) -> list[PlantDeclaration]:
    """What each plant record declares at the period ``dt`` [s] (for the controllers' dry run).

    A record that does not build is left out: :func:`check_plant` names its fault.
    """
    declared = []
    for record in records:
        try:
            declared.append(build_plant(record).declares(dt))
        except (OtmmError, ValueError, TypeError):
            continue
    return declared


def experiment_stages(
    default_plant: Any, controllers: list[ControllerConfig], robot: Robot, q0: FloatArray,
    dt: float, field: str, budget: tuple[int, int] | None = None,
) -> tuple[dict[str, Any], dict[str, list[dict[str, Any]]]]:  # fmt: skip
    """Plant and conditioning records per controller name of one experiment, checked.

    Args:
        default_plant: The experiment's (else the suite's) ``plant`` config, or None.
        controllers: The experiment's controller records.
        robot: The arm.
        q0: Start configuration (nq,).
        dt: Control period [s].
        field: Config path of the experiment.
        budget: ``(steps, max_steps)`` of its runs (see :func:`check_plant`).

    Raises:
        ConfigError: A plant or conditioning stage that cannot run (see :func:`check_plant`).
    """
    plants = {c.name: plant_record(c.plant or default_plant) for c in controllers}
    conditioning = {
        c.name: [dict(s.params, type=s.type) for s in c.conditioning]
        for c in controllers
        if c.conditioning
    }
    for plant in {repr(p): p for p in plants.values()}.values():
        check_plant(plant, robot, q0, dt, f"{field}.plant", budget)
    check_conditioning(conditioning, robot, dt, field)
    return plants, conditioning
